// The session's real-time threads (session.hpp): the haptic thread's 1 kHz ticks (on its own
// deadlines or paced by the device), the simulation thread's steps, and their wind-down.
#include "haptics/session.hpp"

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <iomanip>
#include <sstream>
#include <thread>

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <time.h>

#include <nlohmann/json.hpp>

#include "hal/cpu_latency.hpp"
#include "hal/device_clock.hpp"
#include "hal/mono_clock.hpp"
#include "hal/platform_timer.hpp"
#include "haptics/loop/deadlines.hpp"
#include "haptics/refinement/refinement_schedule.hpp"
#include "haptics/modes/rendering_modes.hpp"

namespace hapticloth::haptics {

namespace {
using devices::mono_now;

using devices::to_timespec;
}  // namespace

void Session::account_tick() {
  const HapticReport& r = loop_->last_report();
  for (int f = 0; f < loop_->fingers(); ++f) {
    r_.max_force = std::max(r_.max_force, loop_->last_command().force[f].norm());
    if (r.finger[f].slipping) ++r_.slip_ticks;
  }
}

void Session::run_realtime(double seconds) {
  start();
  std::atomic<bool> stop_flag{false};
  long elapsed_ticks = 0;  // written by the haptic thread, read after it joined
  r_.haptic = LoopStats{};
  // Real-time scheduling when permitted; a clean fallback (with the reason) when not.
  r_.memory_locked = sc_.try_realtime && mlockall(MCL_CURRENT | MCL_FUTURE) == 0;
  std::unique_ptr<devices::CpuLatencyHold> idle;  // shallow idle states: the deadline's wake-up sooner
  if (sc_.try_realtime) idle = std::make_unique<devices::CpuLatencyHold>();
  std::string note;
  const double period = 1.0 / sc_.haptic_rate;
  const double t_start = mono_now() + 0.01;
  // In real time the refinement's settles run beside the steps (refinement_schedule.hpp).
  sim_->refine_beside_steps();
  // The haptic loop reports the fingertips, then the simulation publishes once, before the
  // loops start.
  loop_->prime(0.0);
  sim_->publish(0.0);
  std::thread sim_thread([&] { sim_thread_loop(t_start, stop_flag); });
  std::thread haptic_thread([&] {
    note = haptic_thread_priority();
    elapsed_ticks = haptic_ticks(seconds, t_start, period);
    realtime_wind_down(elapsed_ticks, t_start, period);
  });
  haptic_thread.join();
  stop_flag = true;
  sim_thread.join();
  r_.sim_time = static_cast<double>(elapsed_ticks) * period;
  r_.scheduling_note = idle ? note + ", " + idle->note() : note;
  if (r_.memory_locked) munlockall();
  stop();
}

// The simulation thread: a step per integrator dt on absolute deadlines, as fast as the step
// allows when behind.
void Session::sim_thread_loop(double t_start, const std::atomic<bool>& stop_flag) {
  double next = t_start;
  while (!stop_flag.load(std::memory_order_relaxed)) {
    const double now = mono_now() - t_start;
    sim_->step(now);
    observe_step();
    next += dt_sim_;
    const double t = mono_now();
    if (next > t) {
      const timespec ts = to_timespec(next);
      clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
    } else {
      next = t;  // behind: run as fast as the step allows
    }
  }
}

// SCHED_FIFO for the calling (haptic) thread when asked and permitted; returns what it got.
std::string Session::haptic_thread_priority() {
  prctl(PR_SET_TIMERSLACK, 1UL, 0, 0, 0);  // wake on the deadline, not up to 50 us later
  if (!sc_.try_realtime) return "real-time scheduling not requested";
  sched_param sp{};
  sp.sched_priority = devices::kHapticThreadPriority;
  const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
  r_.realtime_scheduling = rc == 0;
  return rc == 0 ? "SCHED_FIFO priority " + std::to_string(devices::kHapticThreadPriority)
                 : std::string("SCHED_FIFO refused (") + std::strerror(rc) + "): normal scheduling";
}

// The haptic loop at its rate for `seconds` (or until a stop request): returns the ticks due.
long Session::haptic_ticks(double seconds, double t_start, double period) {
  if (sc_.device_clock) return device_paced_ticks(seconds, t_start, period);
  const long ticks = std::lround(seconds * sc_.haptic_rate);
  long elapsed = 0;
  for (long k = 0; k < ticks && !stop_requested(); ++k) {
    const double deadline = t_start + k * period;
    const double woke = wake_at(deadline);
    r_.haptic.period_error_us.add(std::abs(woke - deadline) * 1e6);
    k = tick_after_wake(k, ticks, woke, t_start, period, r_.haptic);
    elapsed = k + 1;
    const double done = haptic_tick(k, woke, t_start);
    count_deadline(woke, done, t_start + (k + 1) * period, period, r_.haptic);
  }
  return elapsed;
}

// The haptic loop on the device's samples for `seconds` (or until a stop request): a tick as
// each sample arrives (DeviceClock). The period error is how far a tick's interval from the
// last is from the period, between two ticks on samples (the device's own jitter and this
// thread's wake-up together); a tick whose compute overruns the period is a missed deadline.
// Ticks without a sample (the device silent for 1.5 periods) show as samples < ticks in the
// device counters. Returns the ticks due in the time run.
long Session::device_paced_ticks(double seconds, double t_start, double period) {
  const devices::DeviceClock clock(period);
  const double end = t_start + seconds;
  double last = t_start - devices::DeviceClock::kEarliest * period;  // the first tick at t_start at the soonest
  bool last_sampled = false;
  for (long k = 0; !stop_requested(); ++k) {
    const devices::DeviceClock::Tick t = clock.wait(dev_, last);
    if (t.at >= end) break;
    if (t.sampled && last_sampled) r_.haptic.period_error_us.add(std::abs(t.at - last - period) * 1e6);
    last = t.at;
    last_sampled = t.sampled;
    const double done = haptic_tick(k, t.at, t_start);
    count_deadline(t.at, done, t.at + period, period, r_.haptic);
  }
  return std::lround((std::min(mono_now(), end) - t_start) / period);
}

// One tick of the haptic loop at `woke` (CLOCK_MONOTONIC, s), its observers and its compute
// time; returns when it was done.
double Session::haptic_tick(long k, double woke, double t_start) {
  loop_->tick(woke - t_start);
  account_tick();
  notify_tick();
  if (k % 1000 == 999)
    for (auto* o : observers_) o->on_loop_stats(r_.haptic);
  const double done = mono_now();
  r_.haptic.compute_us.add((done - woke) * 1e6);
  ++r_.haptic.ticks;
  return done;
}

// Sleeps to just before `deadline`, then spins the rest: the kernel's wake-up is late by tens
// of microseconds (more on a virtual machine); the spin costs spin_lead of CPU per tick.
// Returns the wake-up.
double Session::wake_at(double deadline) const {
  const timespec ts = to_timespec(deadline - sc_.spin_lead);
  clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
  double woke = mono_now();
  while (woke < deadline) woke = mono_now();
  return woke;
}

// The end (of the run, or a stop signal): zero force through the gate, at the loop rate, on
// the loop's deadline grid from deadline `next` on (or the first one still ahead), so that the
// ticks' times in the log stay where the loop's deadlines are.
void Session::realtime_wind_down(long next, double t_start, double period) {
  long k = std::max(next, static_cast<long>((mono_now() - t_start) / period) + 1);
  for (long j = 0; j < kWindDownTicks; ++j, ++k) {
    const bool done = loop_->wind_down(wake_at(t_start + k * period) - t_start);
    notify_tick();
    if (done) break;
  }
}

// The observers see the haptic loop's last tick.
void Session::notify_tick() noexcept {
  for (auto* o : observers_)
    o->on_haptic_tick(loop_->last_report(), loop_->device_state(), loop_->last_command());
  if (loop_->tactile())
    for (auto* o : observers_) o->on_tactile(loop_->last_report(), *loop_->tactile(), loop_->last_tactile());
}

}  // namespace hapticloth::haptics
