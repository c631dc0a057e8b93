// hapticloth-bench-udp: round trip rig -> server -> rig of the UDP device over loopback.
//
// A rig thread sends state packets at --rate on its own clock and timestamps them; the main
// thread runs the UdpDevice read/write loop and answers every tick with a spring force; the rig
// matches force packets by the echoed sequence.
//
// --clock device (the default): the server loop ticks on the rig's samples (DeviceClock, as
// `hapticloth-server --clock device` does), so the round trip is the server's wake-up on the
// socket plus the tick and the rig's wake-up on the answer, whatever the two clocks' phase: a
// rig on its own clock, as a real one is.
// --clock loop: the server loop ticks on its own absolute deadlines. Both loops then run on one
// clock with a fixed phase: the rig sends each packet --lead-us before a server tick, as a rig
// synchronised to the server would, and the round trip is that lead plus the turnaround. The
// lead must cover the rig's own wake-up lateness, or its packet misses the tick (`not_taken`).
// With free-running clocks the packet would also wait a uniformly distributed 0..1 ms for the
// next tick.
//
// Both loops run SCHED_FIFO by default, as the server's haptic thread does, and the bench holds
// /dev/cpu_dma_latency at 0 as the server's real-time loop does. `turnaround_us` (server tick
// -> force packet at the rig) is the part that does not depend on the phase. The platform's
// timer (hapticloth-bench timer) is measured right after, in the same invocation, and printed
// beside.
//
// Prints one JSON line: percentiles of rtt_us (rig send -> force packet at the rig),
// turnaround_us (server loop awake -> force packet at the rig) and wake_late_us (how late the
// server loop woke: after each tick's deadline with --clock loop, which is the machine's timer
// latency; after the rig sent the sample with --clock device, which is the socket's wake-up);
// loss_pct (state packets never echoed: lost, or superseded by a newer one before the server's
// next read) and samples (packets echoed).

#include <pthread.h>
#include <sched.h>
#include <sys/prctl.h>
#include <time.h>

#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <optional>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <string>
#include <thread>
#include <vector>

#include "cli_checks.hpp"
#include "hal/platform_timer.hpp"

#include "hal/cpu_latency.hpp"
#include "hal/device_clock.hpp"
#include "udp/udp_device.hpp"
#include "udp/wire.hpp"

namespace {

using namespace hapticloth::devices;
using Nanos = std::int64_t;

Nanos now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return Nanos{ts.tv_sec} * 1'000'000'000 + ts.tv_nsec;
}

timespec to_timespec(Nanos t) {
  return {static_cast<time_t>(t / 1'000'000'000), static_cast<long>(t % 1'000'000'000)};
}

void sleep_until(Nanos t) {
  const timespec ts = to_timespec(t);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

/// Timer slack of 1 ns for the calling thread: wake-ups at the deadline, not up to the default
/// 50 us after it (SCHED_FIFO threads have no slack anyway).
void no_timer_slack() { ::prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL); }

bool make_fifo(int priority) {
  sched_param sp{};
  sp.sched_priority = priority;
  return pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp) == 0;
}

struct Config {
  double duration = 10.0;  ///< s
  double rate = 1000.0;    ///< Hz
  double lead_us = 40.0;   ///< the rig sends this long before each server tick
  int fingers = 2;
  bool fifo = true;        ///< as the server's haptic thread (SCHED_FIFO when permitted)
  bool device_clock = true;  ///< the server ticks on the rig's samples (else on its own deadlines)
};

/// Per sequence (index = sequence): when the rig sent it, when the server took it, when its
/// first echo reached the rig; 0 = never.
struct Timeline {
  std::vector<Nanos> sent, taken, echoed;
  explicit Timeline(std::size_t n) : sent(n + 1, 0), taken(n + 1, 0), echoed(n + 1, 0) {}
};

/// The rig: one state packet per period at t0 + k period - lead, receiving force packets in
/// between (ppoll with a nanosecond timeout).
void run_rig(const Config& cfg, std::uint16_t server_port, Nanos t0, Nanos period, long packets,
             Timeline& tl, bool& fifo_ok) {
  no_timer_slack();
  if (cfg.fifo) fifo_ok = make_fifo(80);
  const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  sockaddr_in me{};
  me.sin_family = AF_INET;
  me.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ::bind(fd, reinterpret_cast<sockaddr*>(&me), sizeof me);
  sockaddr_in server = me;
  server.sin_port = htons(server_port);

  std::uint8_t buf[2048];
  auto receive = [&] {
    for (int i = 0; i < 64; ++i) {
      const ssize_t n = ::recv(fd, buf, sizeof buf, MSG_DONTWAIT);
      if (n < 0) return;
      const Nanos t = now_ns();
      udp::ForcePacket f;
      if (udp::parse_force_packet(buf, static_cast<std::size_t>(n), cfg.fingers, f) ==
              udp::ParseResult::Ok &&
          f.sequence >= 1 && f.sequence <= static_cast<std::uint64_t>(packets) &&
          tl.echoed[f.sequence] == 0)
        tl.echoed[f.sequence] = t;
    }
  };
  auto wait_until = [&](Nanos deadline) {
    for (int guard = 0; guard < 100000; ++guard) {
      receive();
      const Nanos left = deadline - now_ns();
      if (left <= 0) return;
      pollfd p{fd, POLLIN, 0};
      const timespec ts = to_timespec(left);
      ::ppoll(&p, 1, &ts, nullptr);
    }
  };

  const Nanos lead = static_cast<Nanos>(cfg.lead_us * 1000.0);
  udp::StatePacket s;
  s.fingers = cfg.fingers;
  for (int i = 0; i < cfg.fingers; ++i)
    s.finger[i].position = Vec3(0.02 * (i % 2 ? 1 : -1), 0.01 * i, 0.0);
  for (long k = 0; k < packets; ++k) {
    wait_until(t0 + k * period - lead);
    s.sequence = static_cast<std::uint64_t>(k + 1);
    s.device_time = static_cast<double>(k) / cfg.rate;
    const std::size_t n = udp::encode_state_packet(s, buf, sizeof buf);
    tl.sent[k + 1] = now_ns();
    ::sendto(fd, buf, n, 0, reinterpret_cast<const sockaddr*>(&server), sizeof server);
  }
  wait_until(t0 + (packets + 20) * period);  // the last answers
  ::close(fd);
}

struct Percentiles {
  double p50 = 0, p99 = 0, p999 = 0, max = 0;
};

Percentiles percentiles(std::vector<double> v) {
  Percentiles p;
  if (v.empty()) return p;
  std::sort(v.begin(), v.end());
  auto at = [&](double q) {
    return v[std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())))];
  };
  p.p50 = at(0.5);
  p.p99 = at(0.99);
  p.p999 = at(0.999);
  p.max = v.back();
  return p;
}

std::string json(const Percentiles& p) {
  char b[160];
  std::snprintf(b, sizeof b, "{\"p50\": %.1f, \"p99\": %.1f, \"p999\": %.1f, \"max\": %.1f}",
                p.p50, p.p99, p.p999, p.max);
  return b;
}

// The command line into `cfg`; an exit code when it is wrong or asked for help.
std::optional<int> parse_options(int argc, char** argv, Config& cfg) {
  CLI::App app{"Round trip rig -> UdpDevice -> rig over loopback; prints JSON."};
  app.add_option("--duration", cfg.duration, "s of streaming")->check(hapticloth::opts::number_in(0.1, 3600.0, false, "s"));
  app.add_option("--rate", cfg.rate, "Hz, rig and server loop")->check(hapticloth::opts::number_in(10.0, 10000.0, false, "Hz"));
  std::string clock = "device";
  app.add_option("--clock", clock, "the server loop ticks on the rig's samples (device, default) or "
                                   "on its own deadlines (loop)")
      ->check(CLI::IsMember({"device", "loop"}));
  app.add_option("--lead-us", cfg.lead_us, "--clock loop: us the rig sends before each server tick")
      ->check(hapticloth::opts::number_in(0.0, 1e6, false, "us"));
  app.add_option("--fingers", cfg.fingers, "fingers per packet")->check(CLI::Range(1, kMaxFingers));
  bool json_flag = true;
  app.add_flag("--json", json_flag, "JSON output (the only format; accepted for uniformity)");
  bool no_fifo = false;
  app.add_flag("--no-fifo", no_fifo, "run both loops at normal scheduling (default: SCHED_FIFO, as "
                                     "the server runs its haptic thread when permitted)");
  if (const int rc = hapticloth::opts::parse(app, argc, argv); rc >= 0) return rc;
  cfg.fifo = !no_fifo;
  cfg.device_clock = clock == "device";
  return std::nullopt;
}

// The server loop: read, a spring force, write; until 20 periods after the last packet. Returns
// how late each tick woke, us (see the header).
std::vector<double> run_server(const Config& cfg, UdpDevice& dev, Nanos t0, Nanos period, long packets,
                               Timeline& tl) {
  DeviceState state;
  DeviceCommand cmd;
  std::vector<double> wake_late;
  wake_late.reserve(static_cast<std::size_t>(packets + 20));
  const DeviceClock device_clock(1e-9 * static_cast<double>(period));
  double last = 1e-9 * static_cast<double>(t0 - period);
  const Nanos end = t0 + (packets + 20) * period;
  for (long k = 0; k < 2 * (packets + 20); ++k) {  // bounded: a tick at least every 1.5 periods
    Nanos t;
    if (cfg.device_clock) {
      last = device_clock.wait(dev, last).at;
      t = static_cast<Nanos>(last * 1e9);
    } else {
      const Nanos tick = t0 + k * period;
      sleep_until(tick);
      t = now_ns();
      wake_late.push_back(1e-3 * static_cast<double>(t - tick));
    }
    if (t >= end) break;
    if (dev.read(1e-9 * static_cast<double>(t), state) == Status::Ok &&
        state.sequence <= static_cast<std::uint64_t>(packets)) {
      tl.taken[state.sequence] = t;
      if (cfg.device_clock) wake_late.push_back(1e-3 * static_cast<double>(t - tl.sent[state.sequence]));
    }
    for (int i = 0; i < cfg.fingers; ++i) cmd.force[i] = -100.0 * state.finger[i].position;
    dev.write(1e-9 * static_cast<double>(t), cmd);
  }
  return wake_late;
}

// Round trips (sent -> echoed) and the server's turnarounds (taken -> echoed), us.
struct RoundTrips {
  std::vector<double> rtt, turnaround;
  long not_taken = 0;  // lost, or superseded by a newer packet before the server's next read
};

RoundTrips round_trips(const Timeline& tl, long packets) {
  RoundTrips r;
  for (long s = 1; s <= packets; ++s) {
    if (tl.taken[s] == 0) ++r.not_taken;
    if (tl.echoed[s] == 0) continue;
    r.rtt.push_back(1e-3 * static_cast<double>(tl.echoed[s] - tl.sent[s]));
    if (tl.taken[s] != 0) r.turnaround.push_back(1e-3 * static_cast<double>(tl.echoed[s] - tl.taken[s]));
  }
  return r;
}

void print_json(const Config& cfg, const RoundTrips& rt, const std::vector<double>& wake_late, Nanos period,
                long packets, const UdpDevice& dev, bool fifo_ok, const std::string& idle_note) {
  const auto& c = dev.counters();
  const double loss = 100.0 * static_cast<double>(packets - static_cast<long>(rt.rtt.size())) /
                      static_cast<double>(std::max(packets, 1L));
  // The platform's own timer right after, over as many wake-ups, in this invocation.
  const hapticloth::devices::TimerFigures platform = hapticloth::devices::measure_timer(packets, 1e-9 * period);
  const Percentiles r = percentiles(rt.rtt);
  std::printf(
      "{\"rtt_us\": %s, \"turnaround_us\": %s, \"wake_late_us\": %s, \"loss_pct\": %.3f, "
      "\"samples\": %zu, \"packets\": %ld, \"not_taken\": %ld, \"clock\": \"%s\", \"lead_us\": %.1f, "
      "\"rate_hz\": %.1f, \"dropped\": %llu, \"send_errors\": %llu, \"fifo\": %s, "
      "\"idle_states\": \"%s\", \"platform_timer\": %s, \"rtt_p99_excess_us\": %.1f}\n",
      json(r).c_str(), json(percentiles(rt.turnaround)).c_str(), json(percentiles(wake_late)).c_str(), loss,
      rt.rtt.size(), packets, rt.not_taken, cfg.device_clock ? "device" : "loop", cfg.lead_us, cfg.rate,
      static_cast<unsigned long long>(c.dropped_total()), static_cast<unsigned long long>(c.send_errors),
      cfg.fifo ? (fifo_ok ? "true" : "\"failed\"") : "false", idle_note.c_str(), platform.to_json().dump().c_str(),
      r.p99 - platform.p99_us);
}

}  // namespace

int main(int argc, char** argv) {
  Config cfg;
  if (const std::optional<int> rc = parse_options(argc, argv, cfg)) return *rc;
  // The CPUs kept out of deep idle states, as the server's real-time loop keeps them.
  const hapticloth::devices::CpuLatencyHold idle;
  DeviceOptions opt;
  opt.driver = "udp";
  opt.udp_bind = "127.0.0.1:0";
  opt.fingers = cfg.fingers;
  opt.rate = cfg.rate;
  UdpDevice dev(opt);
  std::string err = dev.configure();
  if (err.empty()) err = dev.activate();
  if (!err.empty()) {
    std::fprintf(stderr, "hapticloth-bench-udp: %s\n", err.c_str());
    return 1;
  }
  const Nanos period = static_cast<Nanos>(1e9 / cfg.rate);
  const long packets = static_cast<long>(cfg.duration * cfg.rate);
  Timeline tl(static_cast<std::size_t>(packets));
  const Nanos t0 = now_ns() + 100'000'000;  // both loops start in 100 ms
  bool rig_fifo = true, fifo_ok = true;
  std::thread rig(run_rig, std::cref(cfg), dev.local_port(), t0, period, packets, std::ref(tl), std::ref(rig_fifo));
  no_timer_slack();
  if (cfg.fifo) fifo_ok = make_fifo(90);
  const std::vector<double> wake_late = run_server(cfg, dev, t0, period, packets, tl);
  rig.join();
  dev.deactivate();
  print_json(cfg, round_trips(tl, packets), wake_late, period, packets, dev, fifo_ok && rig_fifo, idle.note());
  return 0;
}
