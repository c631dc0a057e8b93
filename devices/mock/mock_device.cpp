#include "mock/mock_device.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace hapticloth::devices {

MockDevice::MockDevice(const DeviceOptions& opt) : DeviceDriver(device_info(opt, "mock")), opt_(opt) {}

MockDevice::MockDevice(const DeviceOptions& opt, Trajectory tr)
    : DeviceDriver(device_info(opt, "mock")), opt_(opt), tr_(std::move(tr)), have_tr_(true) {}

std::string MockDevice::configure() {
  if (const std::string e = devices::validate(info_); !e.empty()) return "mock: " + e;
  try {
    if (!have_tr_) {
      tr_ = opt_.script.empty() ? demo_trajectory(opt_.fingers)
                                : load_trajectory(opt_.script, opt_.fingers);
      have_tr_ = true;
    }
    if (tr_.fingers() != opt_.fingers) return "mock: the trajectory has a different number of fingers";
    tr_.check_inside(opt_.workspace, opt_.script.empty() ? "mock trajectory" : opt_.script);
    if (!opt_.script.empty()) tr_.check_speed(kMaxScriptSpeed, opt_.script);
  } catch (const std::exception& e) {
    return std::string("mock: ") + e.what();
  }
  // The record is opened here, so that an unwritable path stops the server before it starts.
  if (!opt_.record_path.empty())
    if (std::string e = record_.open(opt_.record_path); !e.empty()) return "mock: record: " + e;
  return "";
}

std::string MockDevice::activate() {
  t0_ = -1.0;
  last_ = DeviceState{};
  tactile_ = TactileRecord{};
  if (info_.tactile.vibration())
    for (int f = 0; f < info_.fingers; ++f)
      tactile_.vibration[f].reserve(static_cast<size_t>(info_.tactile.vibration_rate * TactileRecord::kTactileRecordSeconds));
  if (!opt_.record_path.empty() && !record_.is_open())  // a new session after a deactivate
    if (std::string e = record_.open(opt_.record_path); !e.empty()) return "mock: record: " + e;
  return "";
}

void MockDevice::deactivate() {
  const std::string e = record_.close();
  counters_.record_rows = record_.written();
  counters_.record_dropped = record_.dropped();
  if (!e.empty()) throw std::runtime_error("mock: record: " + e);
}

Status MockDevice::read(double now, DeviceState& state) noexcept {
  ++counters_.reads;
  if (!std::isfinite(now)) return Status::Error;
  if (t0_ < 0.0) t0_ = now;
  const double t = now - t0_;
  tr_.sample(info_.fingers, t, now, last_);
  ++counters_.samples;
  state = last_;
  return Status::Ok;
}

Status MockDevice::write(double now, const DeviceCommand& cmd) noexcept {
  ++counters_.writes;
  record_.record(script_time(now), info_.fingers, last_, cmd);
  counters_.record_dropped = record_.dropped();
  return Status::Ok;
}

Status MockDevice::write_tactile(double, const TactileCommand& cmd) noexcept {
  ++tactile_.frames;
  tactile_.last = cmd;
  for (int f = 0; f < info_.fingers; ++f) {
    std::vector<float>& v = tactile_.vibration[f];
    const TactileFrame& fr = cmd.finger[f];
    const size_t room = v.capacity() - v.size(), n = static_cast<size_t>(std::max(fr.samples, 0));
    v.insert(v.end(), fr.vibration.begin(), fr.vibration.begin() + std::min(room, n));  // within the reserve
    tactile_.dropped_samples += n - std::min(room, n);
  }
  return Status::Ok;
}

std::unique_ptr<Device> make_mock_device(const DeviceOptions& opt) {
  return std::make_unique<MockDevice>(opt);
}

}  // namespace hapticloth::devices
