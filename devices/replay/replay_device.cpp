#include "replay/replay_device.hpp"

#include <algorithm>
#include <cmath>

namespace hapticloth::devices {

ReplayDevice::ReplayDevice(const DeviceOptions& opt) : DeviceDriver(device_info(opt, "replay")), opt_(opt) {}

std::string ReplayDevice::configure() {
  if (opt_.replay_path.empty()) return "replay: no device log given (replay_path / --replay FILE)";
  try {
    const auto rows = load_device_log(opt_.replay_path);
    positions_ = Trajectory(opt_.fingers);
    rows_.assign(opt_.fingers, {});
    for (const auto& r : rows) {
      if (r.finger >= opt_.fingers)
        return "replay: " + opt_.replay_path + " has finger " + std::to_string(r.finger) +
               " but the device has " + std::to_string(opt_.fingers) + " fingers";
      positions_.add(r.finger, r.time, r.x);
      rows_[r.finger].push_back(r);
    }
    positions_.check_inside(opt_.workspace, opt_.replay_path);
  } catch (const std::exception& e) {
    return std::string("replay: ") + e.what();
  }
  return "";
}

std::string ReplayDevice::activate() {
  t0_ = -1.0;
  last_ = DeviceState{};
  return "";
}

Status ReplayDevice::read(double now, DeviceState& state) noexcept {
  ++counters_.reads;
  if (!std::isfinite(now)) return Status::Error;
  if (t0_ < 0.0) t0_ = now;
  // Log times are relative to the log's own first sample.
  const double t = now - t0_ + (rows_.empty() || rows_[0].empty() ? 0.0 : rows_[0].front().time);
  positions_.sample(info_.fingers, t, now, last_);
  ++counters_.samples;
  state = last_;
  return Status::Ok;
}

Status ReplayDevice::write(double, const DeviceCommand&) noexcept {
  ++counters_.writes;
  return Status::Ok;
}

Vec3 ReplayDevice::recorded_force(int finger, double t) const noexcept {
  if (finger < 0 || finger >= static_cast<int>(rows_.size()) || rows_[finger].empty()) return Vec3::Zero();
  const auto& r = rows_[finger];
  auto it = std::lower_bound(r.begin(), r.end(), t, [](const LogRow& a, double x) { return a.time < x; });
  if (it == r.end()) return r.back().f;
  if (it != r.begin() && std::abs((it - 1)->time - t) < std::abs(it->time - t)) --it;
  return it->f;
}

std::unique_ptr<Device> make_replay_device(const DeviceOptions& opt) {
  return std::make_unique<ReplayDevice>(opt);
}

}  // namespace hapticloth::devices
