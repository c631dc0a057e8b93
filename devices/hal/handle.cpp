#include "hal/handle.hpp"

#include <stdexcept>

namespace hapticloth::devices {

DeviceHandle::DeviceHandle(std::unique_ptr<Device> d) : dev_(std::move(d)) {
  if (!dev_) throw std::invalid_argument("device handle: no driver");
}

namespace {

// "" if a transition named `step` may start in state `now`, else why not.
std::string not_in(const char* step, Lifecycle now, Lifecycle from) {
  if (now == from) return "";
  return std::string(step) + ": device is " + to_string(now) + ", not " + to_string(from);
}

// Runs the driver's side of a transition: its error, or what it threw prefixed by the step's
// name (and `threw` set).
template <class F>
std::string call_driver(const char* step, F&& driver_step, bool& threw) {
  try {
    return driver_step();
  } catch (const std::exception& e) {
    threw = true;
    return std::string(step) + ": " + e.what();
  }
}

// A driver's Error on the real-time path turns the handle Failed.
Status after_driver(Status st, Lifecycle& state, bool& failed) noexcept {
  if (st == Status::Error) {
    state = Lifecycle::Failed;
    failed = true;
  }
  return st;
}

}  // namespace

std::string DeviceHandle::configure() {
  error_ = not_in("configure", state_, Lifecycle::Unconfigured);
  if (!error_.empty()) return error_;
  bool threw = false;
  error_ = call_driver("configure", [&] { return dev_->configure(); }, threw);
  if (threw) {
    state_ = Lifecycle::Failed;
    return error_;
  }
  if (error_.empty())
    if (const std::string e = validate(dev_->info()); !e.empty()) error_ = "configure: " + e;
  if (error_.empty()) state_ = Lifecycle::Inactive;
  return error_;
}

std::string DeviceHandle::activate() {
  error_ = not_in("activate", state_, Lifecycle::Inactive);
  if (!error_.empty()) return error_;
  bool threw = false;
  error_ = call_driver("activate", [&] { return dev_->activate(); }, threw);
  if (error_.empty()) {
    state_ = Lifecycle::Active;
    failed_ = false;
  }
  return error_;
}

void DeviceHandle::deactivate() {
  if (state_ != Lifecycle::Active && state_ != Lifecycle::Failed) return;
  try {
    dev_->deactivate();
  } catch (const std::exception& e) {
    error_ = std::string("deactivate: ") + e.what();
  }
  state_ = Lifecycle::Inactive;
}

Status DeviceHandle::read(double now, DeviceState& s) noexcept {
  if (state_ != Lifecycle::Active) return Status::Error;
  return after_driver(dev_->read(now, s), state_, failed_);
}

Status DeviceHandle::write(double now, const DeviceCommand& c) noexcept {
  if (state_ != Lifecycle::Active) return Status::Error;
  return after_driver(dev_->write(now, c), state_, failed_);
}

Status DeviceHandle::write_tactile(double now, const TactileCommand& c) noexcept {
  if (state_ != Lifecycle::Active) return Status::Error;
  return after_driver(dev_->write_tactile(now, c), state_, failed_);
}

bool DeviceHandle::await_sample(double until) noexcept {
  return state_ == Lifecycle::Active && dev_->await_sample(until);
}

}  // namespace hapticloth::devices
