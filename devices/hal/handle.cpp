#include "hal/handle.hpp"

#include <stdexcept>

namespace hapticloth::devices {

DeviceHandle::DeviceHandle(std::unique_ptr<Device> d) : dev_(std::move(d)) {
  if (!dev_) throw std::invalid_argument("device handle: no driver");
}

std::string DeviceHandle::configure() {
  if (state_ != Lifecycle::Unconfigured) {
    error_ = std::string("configure: device is ") + to_string(state_) + ", not unconfigured";
    return error_;
  }
  try {
    error_ = dev_->configure();
  } catch (const std::exception& e) {
    error_ = std::string("configure: ") + e.what();
    state_ = Lifecycle::Failed;
    return error_;
  }
  if (error_.empty())
    if (const std::string e = validate(dev_->info()); !e.empty()) error_ = "configure: " + e;
  if (error_.empty()) state_ = Lifecycle::Inactive;
  return error_;
}

std::string DeviceHandle::activate() {
  if (state_ != Lifecycle::Inactive) {
    error_ = std::string("activate: device is ") + to_string(state_) + ", not inactive";
    return error_;
  }
  try {
    error_ = dev_->activate();
  } catch (const std::exception& e) {
    error_ = std::string("activate: ") + e.what();
  }
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
  const Status st = dev_->read(now, s);
  if (st == Status::Error) {
    state_ = Lifecycle::Failed;
    failed_ = true;
  }
  return st;
}

Status DeviceHandle::write(double now, const DeviceCommand& c) noexcept {
  if (state_ != Lifecycle::Active) return Status::Error;
  const Status st = dev_->write(now, c);
  if (st == Status::Error) {
    state_ = Lifecycle::Failed;
    failed_ = true;
  }
  return st;
}

}  // namespace hapticloth::devices
