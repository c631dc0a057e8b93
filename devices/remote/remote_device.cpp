#include "remote/remote_device.hpp"

#include <cmath>
#include <functional>
#include <sstream>

#include "mock/trajectory.hpp"

namespace hapticloth::devices {

namespace {
bool finite(const Vec3& p) { return p.allFinite(); }
std::string fmt(const Vec3& p) {
  std::ostringstream s;
  s << "(" << p.x() << ", " << p.y() << ", " << p.z() << ")";
  return s.str();
}
}  // namespace

RemoteDevice::RemoteDevice(const DeviceOptions& opt) : DeviceDriver(device_info(opt, "remote")), opt_(opt) {}

std::string RemoteDevice::configure() {
  if (const std::string e = devices::validate(info_); !e.empty()) return "remote: " + e;
  Plan proto;
  proto.t.resize(kMaxPoints);
  proto.p.resize(kMaxPoints);
  slot_.clear();
  for (int f = 0; f < opt_.fingers; ++f) slot_.push_back(std::make_unique<TripleBuffer<Plan>>(proto));
  // Rest where the script (if any) or the demo trajectory starts, pulled inside the workspace.
  Trajectory start;
  try {
    start = opt_.script.empty() ? demo_trajectory(opt_.fingers) : load_trajectory(opt_.script, opt_.fingers);
  } catch (const std::exception& e) {
    return std::string("remote: ") + e.what();
  }
  for (int f = 0; f < opt_.fingers; ++f) {
    const Trajectory& src = start.keys(f).empty() ? demo_trajectory(opt_.fingers) : start;
    const Vec3 p = src.keys(f).front().p.cwiseMax(opt_.workspace.min).cwiseMin(opt_.workspace.max);
    follow_[f] = Follow{};
    follow_[f].start = p;
    last_.finger[f].position = p;
    last_.finger[f].velocity.setZero();
    for (int k = 0; k < 3; ++k) where_[f][k].store(p[k], std::memory_order_relaxed);
  }
  return "";
}

std::string RemoteDevice::activate() {
  last_.sequence = 0;
  last_.received_time = -1.0;
  return "";
}

void RemoteDevice::deactivate() {}

void RemoteDevice::set_max_speed(double v) {
  if (std::isfinite(v) && v > 0.0) max_speed_.store(v, std::memory_order_relaxed);
}

std::string RemoteDevice::validate(const TrajectoryCommand& c) const {
  const int n = static_cast<int>(c.times.size());
  if (slot_.empty()) return "the remote device is not configured";
  if (c.finger < 0 || c.finger >= opt_.fingers)
    return "finger " + std::to_string(c.finger) + " out of range (0.." + std::to_string(opt_.fingers - 1) + ")";
  if (n < 1) return "no points";
  if (n > kMaxPoints) return std::to_string(n) + " points, more than " + std::to_string(kMaxPoints);
  if (c.positions.size() != c.times.size()) return "times and positions differ in length";
  const double vmax = max_speed();
  for (int i = 0; i < n; ++i) {
    const std::string at = "point " + std::to_string(i) + ": ";
    if (!std::isfinite(c.times[i]) || !finite(c.positions[i])) return at + "not finite";
    if (i == 0 && c.times[0] < 0.0) return at + "negative time";
    if (i > 0 && !(c.times[i] > c.times[i - 1])) return at + "times not strictly increasing";
    if (!info_.workspace.contains(c.positions[i]))
      return at + fmt(c.positions[i]) + " outside the workspace " + fmt(info_.workspace.min) +
             " - " + fmt(info_.workspace.max);
    if (i > 0) {
      const double v = (c.positions[i] - c.positions[i - 1]).norm() / (c.times[i] - c.times[i - 1]);
      if (v > vmax * (1.0 + 1e-9))
        return at + "speed " + std::to_string(v) + " m/s above the limit " + std::to_string(vmax);
    }
  }
  Vec3 here;
  for (int k = 0; k < 3; ++k) here[k] = where_[c.finger][k].load(std::memory_order_relaxed);
  const double leg = (c.positions[0] - here).norm();
  if (leg > vmax * c.times[0] + kStartTolerance)
    return "first point " + fmt(c.positions[0]) + " is " + std::to_string(leg) +
           " m from the finger, too far to reach at " + std::to_string(vmax) + " m/s by t = " +
           std::to_string(c.times[0]) + " s";
  return "";
}

std::string RemoteDevice::submit(const TrajectoryCommand& c) {
  std::lock_guard<std::mutex> lock(submit_mu_);
  std::string why = validate(c);
  if (!why.empty()) return why;
  Plan& p = slot_[c.finger]->back();
  p.n = static_cast<int>(c.times.size());
  std::copy(c.times.begin(), c.times.end(), p.t.begin());
  std::copy(c.positions.begin(), c.positions.end(), p.p.begin());
  p.batch = c.utime == 0 ? 0 : (std::hash<std::string>{}(c.source) * 1000003u) ^ static_cast<std::uint64_t>(c.utime);
  slot_[c.finger]->publish();
  return "";
}

// Takes the finger's new plan at loop time `now`. Its time 0 is now, unless it belongs to the
// batch taken last (the same source and utime: the fingers of one pinch, sent together but
// arriving ticks apart): then it is the batch's time 0, so that the fingers move in step, and
// the first leg, from where the finger is, takes what is left of it. A plan taken too late for
// that (its first point out of reach by its time at the speed limit) starts now.
void RemoteDevice::take(Follow& fo, double now, const FingerState& at) noexcept {
  const Plan& pl = *fo.plan;
  fo.seg = 0;
  fo.start = at.position;
  fo.t0 = now;
  fo.leg_from = 0.0;
  if (pl.batch != 0 && pl.batch == batch_) {
    const double late = now - batch_t0_, left = pl.t[0] - late;
    if (left > 0.0 && (pl.p[0] - at.position).norm() <= max_speed() * left + kStartTolerance) {
      fo.t0 = batch_t0_;
      fo.leg_from = late;
    }
    return;
  }
  batch_ = pl.batch;
  batch_t0_ = now;
}

void RemoteDevice::follow(int f, double now, FingerState& out) noexcept {
  Follow& fo = follow_[f];
  if (slot_[f]->acquire()) {
    fo.plan = &slot_[f]->front();
    take(fo, now, out);
    taken_.fetch_add(1, std::memory_order_relaxed);
  }
  if (fo.plan == nullptr) {
    out.velocity.setZero();
    return;
  }
  const Plan& pl = *fo.plan;
  const double t = now - fo.t0;
  if (t < pl.t[0]) {  // the leg from where the finger was to the first point
    const Vec3 d = pl.p[0] - fo.start;
    const double leg = pl.t[0] - fo.leg_from;
    out.velocity = d / leg;
    out.position = fo.start + d * ((t - fo.leg_from) / leg);
    return;
  }
  while (fo.seg + 1 < pl.n && pl.t[fo.seg + 1] <= t) ++fo.seg;
  if (fo.seg + 1 >= pl.n) {
    out.position = pl.p[pl.n - 1];
    out.velocity.setZero();
    return;
  }
  const double span = pl.t[fo.seg + 1] - pl.t[fo.seg];
  const Vec3 d = pl.p[fo.seg + 1] - pl.p[fo.seg];
  out.velocity = d / span;
  out.position = pl.p[fo.seg] + d * ((t - pl.t[fo.seg]) / span);
}

Status RemoteDevice::read(double now, DeviceState& state) noexcept {
  ++counters_.reads;
  if (!std::isfinite(now) || slot_.empty()) return Status::Error;
  for (int f = 0; f < info_.fingers; ++f) {
    follow(f, now, last_.finger[f]);
    for (int k = 0; k < 3; ++k) where_[f][k].store(last_.finger[f].position[k], std::memory_order_relaxed);
  }
  last_.device_time = now;
  last_.received_time = now;
  ++last_.sequence;
  ++counters_.samples;
  state = last_;
  return Status::Ok;
}

Status RemoteDevice::write(double, const DeviceCommand& cmd) noexcept {
  ++counters_.writes;
  last_cmd_ = cmd;
  return Status::Ok;
}

std::unique_ptr<Device> make_remote_device(const DeviceOptions& opt) {
  return std::make_unique<RemoteDevice>(opt);
}

}  // namespace hapticloth::devices
