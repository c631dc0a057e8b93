#include "composite/composite_device.hpp"

#include <algorithm>
#include <stdexcept>

#include "registry.hpp"

namespace hapticloth::devices {

namespace {

// The options of part i: one finger, the device's limits, its own driver and endpoint.
DeviceOptions part_options(const DeviceOptions& opt, std::size_t i) {
  DeviceOptions p = opt.parts[i];
  const std::string where = "part " + std::to_string(i) + ": ";
  if (!driver_paces_loop(p.driver))
    throw std::invalid_argument(where + "driver '" + p.driver + "': a part is a one-finger rig that "
                                "streams its samples (udp)");
  p.fingers = 1;
  p.workspace = opt.workspace;
  p.max_force = opt.max_force;
  p.max_stiffness = opt.max_stiffness;
  p.rate = opt.rate;
  p.tactile = opt.tactile;  // each part carries its finger's display
  p.stale_after = opt.stale_after;
  p.stale_ramp = opt.stale_ramp;
  p.parts.clear();
  return p;
}

// The part's own gate: its watchdog and fade; the loop's gate limits force and slew.
GateConfig part_gate_config(const DeviceOptions& opt) {
  GateConfig g;
  g.max_force = opt.max_force;
  g.slew_rate = 1e9;  // the loop's gate limits the slew
  g.watchdog = opt.stale_after;
  g.ramp_time = opt.stale_ramp;
  return g;
}

// The device's status from its parts': Error over NoData over Ok.
Status worse(Status a, Status b) noexcept {
  if (a == Status::Error || b == Status::Error) return Status::Error;
  return a == Status::NoData || b == Status::NoData ? Status::NoData : Status::Ok;
}

}  // namespace

CompositeDevice::CompositeDevice(const DeviceOptions& opt) {
  if (opt.parts.size() < static_cast<std::size_t>(kMinFingers) || opt.parts.size() > static_cast<std::size_t>(kMaxFingers))
    throw std::invalid_argument("parts: a composite device has " + std::to_string(kMinFingers) + " to " +
                                std::to_string(kMaxFingers) + " parts (one finger each), not " +
                                std::to_string(opt.parts.size()));
  info_ = device_info(opt, "composite");
  info_.fingers = static_cast<int>(opt.parts.size());
  for (std::size_t i = 0; i < opt.parts.size(); ++i) {
    const DeviceOptions p = part_options(opt, i);
    std::unique_ptr<Device> d;
    try {
      d = make_device(p);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("part " + std::to_string(i) + ": " + e.what());
    }
    info_.name += (i ? ", " : " (") + d->info().name + (i + 1 == opt.parts.size() ? ")" : "");
    // The gate is of the whole device (a gate checks the device it guards has 2+ fingers);
    // only finger 0 of its command is ever set.
    parts_.push_back(Part{std::move(d), SafetyGate(info_, part_gate_config(opt)), {}});
  }
}

std::string CompositeDevice::configure() {
  for (std::size_t i = 0; i < parts_.size(); ++i)
    if (std::string e = parts_[i].device->configure(); !e.empty()) return "part " + std::to_string(i) + ": " + e;
  return "";
}

std::string CompositeDevice::activate() {
  for (std::size_t i = 0; i < parts_.size(); ++i) {
    if (std::string e = parts_[i].device->activate(); !e.empty()) {
      for (std::size_t j = 0; j < i; ++j) parts_[j].device->deactivate();
      return "part " + std::to_string(i) + ": " + e;
    }
    parts_[i].gate.reset();
    parts_[i].state = DeviceState{};
  }
  state_ = DeviceState{};
  return "";
}

void CompositeDevice::deactivate() {
  std::string first_error;
  for (auto& p : parts_) {
    try {
      p.device->deactivate();
    } catch (const std::runtime_error& e) {  // a part's record could not be written
      if (first_error.empty()) first_error = e.what();
    }
  }
  sum_counters();
  if (!first_error.empty()) throw std::runtime_error(first_error);
}

// Each part's newest sample gives its finger. The device's sample is as fresh as its freshest
// part (the loop's gate trips only when every part is silent); a part that falls silent is
// faded out by its own gate in write().
Status CompositeDevice::read(double now, DeviceState& state) noexcept {
  bool any = false;
  for (std::size_t i = 0; i < parts_.size(); ++i) {
    Part& p = parts_[i];
    const Status s = p.device->read(now, p.state);
    if (s == Status::Error) return Status::Error;
    if (s != Status::Ok) continue;
    any = true;
    state_.finger[i] = p.state.finger[0];
    state_.device_time = std::max(state_.device_time, p.state.device_time);
    state_.received_time = std::max(state_.received_time, p.state.received_time);
  }
  // A part not heard from yet reads as the device origin (which may be inside the cloth), and
  // one silent past its watchdog as wherever it was: neither finger is there.
  state_.absent = 0;
  for (std::size_t i = 0; i < parts_.size(); ++i)
    if (!parts_[i].gate.fresh(now, parts_[i].state.received_time)) state_.absent |= 1u << i;
  sum_counters();
  if (!any) return Status::NoData;
  ++state_.sequence;
  state = state_;
  return Status::Ok;
}

// send(part, i) for each part, then the parts' counters summed: the worst status.
template <class Send>
Status CompositeDevice::to_each_part(Send&& send) noexcept {
  Status worst = Status::Ok;
  for (std::size_t i = 0; i < parts_.size(); ++i) worst = worse(worst, send(parts_[i], i));
  sum_counters();
  return worst;
}

// Finger i's force to part i, through the part's own gate (its watchdog and fade).
Status CompositeDevice::write(double now, const DeviceCommand& cmd) noexcept {
  return to_each_part([&](Part& p, std::size_t i) {
    DeviceCommand one, gated;
    one.force[0] = cmd.force[i];
    one.flags = cmd.flags;
    p.gate.apply(now, p.state.received_time, one, gated);
    return p.device->write(now, gated);
  });
}

// Finger i's tactile frame to part i, through the part's own gate (its fade).
Status CompositeDevice::write_tactile(double now, const TactileCommand& cmd) noexcept {
  return to_each_part([&](Part& p, std::size_t i) {
    TactileCommand one, gated;
    one.finger[0] = cmd.finger[i];
    one.flags = cmd.flags;
    p.gate.apply_tactile(one, gated);
    return p.device->write_tactile(now, gated);
  });
}

void CompositeDevice::sum_counters() noexcept {
  DeviceCounters c;
  for (const auto& p : parts_) {
    const DeviceCounters& q = p.device->counters();
    c.reads += q.reads;
    c.samples += q.samples;
    c.writes += q.writes;
    c.tactile_sent += q.tactile_sent;
    c.dropped_malformed += q.dropped_malformed;
    c.dropped_version += q.dropped_version;
    c.dropped_duplicate += q.dropped_duplicate;
    c.dropped_reordered += q.dropped_reordered;
    c.dropped_out_of_range += q.dropped_out_of_range;
    c.dropped_backlog += q.dropped_backlog;
    c.dropped_stale += q.dropped_stale;
    c.dropped_other_sender += q.dropped_other_sender;
    c.send_errors += q.send_errors;
    c.record_rows += q.record_rows;
    c.record_dropped += q.record_dropped;
  }
  counters_ = c;
}

std::unique_ptr<Device> make_composite_device(const DeviceOptions& opt) {
  return std::make_unique<CompositeDevice>(opt);
}

}  // namespace hapticloth::devices
