#include "udp/udp_device.hpp"

#include <arpa/inet.h>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fcntl.h>
#include <poll.h>
#include <stdexcept>
#include <sys/socket.h>
#include <unistd.h>

#include "hal/mono_clock.hpp"

namespace hapticloth::devices {

namespace {

/// Receive buffer asked of the kernel: a few hundred packets, so a loop that stalls for a
/// moment loses nothing (read() still takes only the newest).
constexpr int kReceiveBufferBytes = 1 << 20;

std::string errno_text(const char* what) { return std::string(what) + ": " + std::strerror(errno); }

/// Errors after which the socket is still usable: the next tick may succeed.
bool transient_send_error(int e) {
  return e == EAGAIN || e == EWOULDBLOCK || e == ENOBUFS || e == EINTR || e == ECONNREFUSED ||
         e == EHOSTUNREACH || e == ENETUNREACH || e == ENETDOWN || e == EPERM;
}

}  // namespace

std::string parse_udp_endpoint(const std::string& text, UdpEndpoint& out) {
  const auto bad = [&](const std::string& why) {
    return "udp_bind '" + text + "': " + why + " (expected HOST:PORT, for example 127.0.0.1:" +
           std::to_string(kDefaultUdpPort) + ")";
  };
  const auto colon = text.rfind(':');
  if (colon == std::string::npos) return bad("no ':PORT'");
  const std::string host = text.substr(0, colon), port = text.substr(colon + 1);
  if (port.empty() || port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos)
    return bad("port is not a number in 0..65535");
  const unsigned long p = std::stoul(port);
  if (p > 65535) return bad("port is above 65535");
  in_addr a{};
  if (host == "localhost") {
    a.s_addr = htonl(INADDR_LOOPBACK);
  } else if (host.empty() || inet_pton(AF_INET, host.c_str(), &a) != 1) {
    return bad("host is not a numeric IPv4 address or 'localhost'");
  }
  out.address = ntohl(a.s_addr);
  out.port = static_cast<std::uint16_t>(p);
  return "";
}

UdpDevice::UdpDevice(const DeviceOptions& opt) : opt_(opt) {
  const std::string err = parse_udp_endpoint(opt.udp_bind, bind_);
  if (!err.empty()) throw std::invalid_argument(err);
  // One finger is a part of a composite device (two single-finger arms for a pinch).
  if (opt.fingers < 1 || opt.fingers > kMaxFingers)
    throw std::invalid_argument("fingers " + std::to_string(opt.fingers) + ": a UDP rig has 1 to " +
                                std::to_string(kMaxFingers));
  info_ = device_info(opt, "udp " + opt.udp_bind);
}

UdpDevice::~UdpDevice() { close_socket(); }

std::string UdpDevice::open_socket() {
  if (fd_ >= 0) return "";
  const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd < 0) return errno_text("udp: socket");
  int rcvbuf = kReceiveBufferBytes;
  ::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);  // best effort
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(bind_.address);
  a.sin_port = htons(bind_.port);
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&a), sizeof a) != 0) {
    const std::string err = errno_text(("udp: bind " + opt_.udp_bind).c_str());
    ::close(fd);
    return err;
  }
  socklen_t len = sizeof a;
  if (::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len) != 0) {
    const std::string err = errno_text("udp: getsockname");
    ::close(fd);
    return err;
  }
  fd_ = fd;
  local_port_ = ntohs(a.sin_port);
  return "";
}

void UdpDevice::close_socket() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

std::string UdpDevice::configure() {
  try {
    if (std::string e = open_socket(); !e.empty()) return e;
    // The record is opened here, so that an unwritable path stops the server before it starts.
    if (!opt_.record_path.empty())
      if (std::string e = record_.open(opt_.record_path); !e.empty()) return "udp: record: " + e;
    return "";
  } catch (const std::exception& e) {  // std::string allocation only
    return std::string("udp: ") + e.what();
  }
}

std::string UdpDevice::activate() {
  try {
    const std::string err = open_socket();
    if (!err.empty()) return err;
    if (!opt_.record_path.empty() && !record_.is_open())  // a new session after a deactivate
      if (std::string e = record_.open(opt_.record_path); !e.empty()) return "udp: record: " + e;
  } catch (const std::exception& e) {
    return std::string("udp: ") + e.what();
  }
  // A new session: accept whatever sequence and sender the rig starts from, and nothing the
  // socket queued before it.
  have_sample_ = false;
  have_offset_ = false;
  recorded_newest_ = true;
  drain_backlog();
  return "";
}

// Off the real-time path: discards the datagrams queued before the session (bounded).
void UdpDevice::drain_backlog() {
  for (int i = 0; i < kMaxBacklog; ++i) {
    const ssize_t n = ::recv(fd_, rx_.data(), rx_.size(), MSG_DONTWAIT | MSG_TRUNC);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return;  // EAGAIN: empty
    ++counters_.dropped_backlog;
  }
}

bool UdpDevice::same_sender(const sockaddr_in& a, const sockaddr_in& b) noexcept {
  return a.sin_addr.s_addr == b.sin_addr.s_addr && a.sin_port == b.sin_port;
}

// The rig's clock against the loop's (see the header): every valid packet read at `now` is
// evidence of the least offset; a rig whose clock jumped back (nothing taken for kClockResync)
// is taken afresh.
void UdpDevice::note_offset(double now, const udp::StatePacket& p) noexcept {
  const double offset = now - p.device_time;
  const bool resync = have_sample_ && now - taken_time_ > kClockResync;
  if (!have_offset_ || resync || offset < min_offset_ + kClockDrift * (now - offset_time_)) {
    min_offset_ = offset;
    offset_time_ = now;
    have_offset_ = true;
  }
}

// How long the sample waited: its offset above the least seen (which creeps at kClockDrift).
double UdpDevice::age(double now, const udp::StatePacket& p) const noexcept {
  return (now - p.device_time) - (min_offset_ + kClockDrift * (now - offset_time_));
}

void UdpDevice::deactivate() {
  if (fd_ >= 0 && have_sample_) {
    bool broken = false;
    send_force(state_.received_time, DeviceCommand{}, broken);  // zero forces, flags 0
  }
  close_socket();
  const std::string e = record_.close();
  counters_.record_rows = record_.written();
  counters_.record_dropped = record_.dropped();
  if (!e.empty()) throw std::runtime_error("udp: record: " + e);
}

void UdpDevice::take(const udp::StatePacket& p, const sockaddr_in& from) {
  newest_ = p;
  have_sample_ = true;
  peer_ = from;
  ++counters_.samples;
}

Status UdpDevice::read(double now, DeviceState& state) noexcept {
  ++counters_.reads;
  if (fd_ < 0) return Status::Error;
  bool fresh = false;
  const udp::StatePacket rendered = newest_;  // the sample the state (and the replies) are of
  for (int i = 0; i < kMaxDatagramsPerRead; ++i) {
    sockaddr_in from{};
    socklen_t from_len = sizeof from;
    // MSG_TRUNC: the datagram's real length even if it is longer than the buffer.
    const ssize_t n = ::recvfrom(fd_, rx_.data(), rx_.size(), MSG_DONTWAIT | MSG_TRUNC,
                                 reinterpret_cast<sockaddr*>(&from), &from_len);
    if (n < 0) {
      if (errno == EINTR) continue;
      if (errno == EAGAIN || errno == EWOULDBLOCK || errno == ECONNREFUSED) break;
      return Status::Error;
    }
    if (static_cast<std::size_t>(n) > rx_.size()) {
      ++counters_.dropped_malformed;
      continue;
    }
    udp::StatePacket p;
    switch (udp::parse_state_packet(rx_.data(), static_cast<std::size_t>(n), info_.fingers,
                                    info_.workspace, p)) {
      case udp::ParseResult::Malformed: ++counters_.dropped_malformed; continue;
      case udp::ParseResult::BadVersion: ++counters_.dropped_version; continue;
      case udp::ParseResult::OutOfRange: ++counters_.dropped_out_of_range; continue;
      case udp::ParseResult::Ok: break;
    }
    if (have_sample_ && !same_sender(from, peer_)) {  // the session is the first rig's
      ++counters_.dropped_other_sender;
      continue;
    }
    // Sequence rules against the newest sample taken (proto/udp_device.md).
    if (have_sample_ && p.sequence == newest_.sequence) {
      ++counters_.dropped_duplicate;
      continue;
    }
    if (have_sample_ && p.sequence < newest_.sequence) {
      ++counters_.dropped_reordered;
      continue;
    }
    note_offset(now, p);
    take(p, from);
    fresh = true;
  }
  if (!fresh) return Status::NoData;
  // The newest sample found is older than the watchdog (a backlog read 256 at a time, or a
  // queue built while the loop stalled): not rendered from, and the state the gate sees keeps
  // ageing. Older ones in the same read were superseded, whatever their age.
  if (age(now, newest_) > opt_.stale_after) {
    --counters_.samples;
    ++counters_.dropped_stale;
    newest_ = rendered;  // force packets keep echoing the sample their force is of
    return Status::NoData;
  }
  taken_time_ = now;

  state_.device_time = newest_.device_time;
  state_.received_time = now;
  state_.sequence = newest_.sequence;
  for (int f = 0; f < kMaxFingers; ++f)
    state_.finger[f] = f < newest_.fingers ? newest_.finger[f] : FingerState{};
  recorded_newest_ = false;
  state = state_;
  return Status::Ok;
}

bool UdpDevice::await_sample(double until) noexcept {
  if (fd_ < 0) return false;
  for (int guard = 0; guard < 1000; ++guard) {  // EINTR retries, bounded
    const double left = until - mono_now();
    pollfd p{fd_, POLLIN, 0};
    const timespec ts = to_timespec(left > 0.0 ? left : 0.0);
    const int rc = ::ppoll(&p, 1, &ts, nullptr);
    if (rc > 0) return (p.revents & POLLIN) != 0;
    if (rc == 0 || errno != EINTR) return false;
  }
  return false;
}

// One datagram to the session's rig; false (counted in send_errors) if it did not go out whole,
// `broken` if the socket will not send again.
bool UdpDevice::send_datagram(const std::uint8_t* data, std::size_t n, bool& broken) noexcept {
  for (int attempt = 0; attempt < 2; ++attempt) {  // one retry after EINTR
    const ssize_t sent = ::sendto(fd_, data, n, MSG_DONTWAIT, reinterpret_cast<const sockaddr*>(&peer_), sizeof peer_);
    if (sent == static_cast<ssize_t>(n)) return true;
    if (sent < 0 && errno == EINTR && attempt == 0) continue;
    ++counters_.send_errors;
    broken = sent < 0 && !transient_send_error(errno);
    return false;
  }
  return false;
}

bool UdpDevice::send_force(double now, const DeviceCommand& cmd, bool& broken) noexcept {
  udp::ForcePacket fp;
  fp.sequence = newest_.sequence;
  fp.server_time = std::isfinite(now) ? now : 0.0;
  fp.flags = cmd.flags;
  fp.fingers = info_.fingers;
  for (int f = 0; f < info_.fingers; ++f) {
    // Defence in depth: the safety gate upstream already replaces non-finite forces.
    if (cmd.force[f].allFinite()) {
      fp.force[f] = cmd.force[f];
    } else {
      fp.force[f].setZero();
      fp.flags |= kFlagFault;
    }
  }
  const std::size_t n = udp::encode_force_packet(fp, tx_.data(), tx_.size());
  if (!send_datagram(tx_.data(), n, broken)) return false;
  ++counters_.writes;
  if (!recorded_newest_ && record_.is_open()) {
    DeviceCommand sent;
    sent.flags = fp.flags;
    for (int f = 0; f < info_.fingers; ++f) sent.force[f] = fp.force[f];
    record_.record(state_.received_time, info_.fingers, state_, sent);
    counters_.record_dropped = record_.dropped();
  }
  recorded_newest_ = true;
  return true;
}

Status UdpDevice::write(double now, const DeviceCommand& cmd) noexcept {
  if (fd_ < 0) return Status::Error;
  if (!have_sample_) return Status::NoData;
  bool broken = false;
  if (send_force(now, cmd, broken)) return Status::Ok;
  return broken ? Status::Error : Status::NoData;
}

Status UdpDevice::write_tactile(double now, const TactileCommand& cmd) noexcept {
  if (fd_ < 0) return Status::Error;
  if (!have_sample_ || !info_.tactile.any()) return Status::NoData;
  const TactileCapability& c = info_.tactile;
  udp::TactilePacket tp;
  tp.sequence = newest_.sequence;
  tp.server_time = std::isfinite(now) ? now : 0.0;
  tp.flags = cmd.flags;
  tp.sample_rate = c.vibration_rate;
  tp.fingers = info_.fingers;
  tp.samples = c.vibration() ? static_cast<int>(std::lround(c.vibration_rate / info_.nominal_rate)) : 0;
  tp.rows = c.pin_rows;
  tp.cols = c.pin_cols;
  tp.frames = cmd;
  const std::size_t n = udp::encode_tactile_packet(tp, tactile_tx_.data(), tactile_tx_.size());
  bool broken = false;
  if (n > 0 && send_datagram(tactile_tx_.data(), n, broken)) {
    ++counters_.tactile_sent;
    return Status::Ok;
  }
  return broken ? Status::Error : Status::NoData;
}

std::unique_ptr<Device> make_udp_device(const DeviceOptions& opt) {
  return std::make_unique<UdpDevice>(opt);
}

}  // namespace hapticloth::devices
