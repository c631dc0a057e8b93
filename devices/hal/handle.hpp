// The lifecycle around a driver: the loop holds a DeviceHandle, never a bare Device.
// It enforces the transitions, skips read/write unless active, and turns a driver's Error into
// the Failed state (after which only deactivate is possible; activate again from Inactive).
#pragma once

#include <memory>
#include <string>

#include "hal/device.hpp"

namespace hapticloth::devices {

class DeviceHandle {
 public:
  explicit DeviceHandle(std::unique_ptr<Device> d);

  Lifecycle state() const { return state_; }
  /// Unconfigured -> Inactive. Returns "" or the error (state unchanged, or Failed if the
  /// driver threw).
  std::string configure();
  /// Inactive -> Active.
  std::string activate();
  /// Active or Failed -> Inactive. Always safe to call.
  void deactivate();

  /// Real-time path. Error (without calling the driver) unless Active; a driver Error moves
  /// the handle to Failed.
  Status read(double now, DeviceState& s) noexcept;
  Status write(double now, const DeviceCommand& c) noexcept;
  Status write_tactile(double now, const TactileCommand& c) noexcept;
  /// Real-time path: the driver's await_sample while Active; false at once otherwise.
  bool await_sample(double until) noexcept;

  Device& device() { return *dev_; }
  const Device& device() const { return *dev_; }
  const DeviceInfo& info() const { return dev_->info(); }
  /// The last error message of a failed transition.
  const std::string& last_error() const { return error_; }
  /// Whether the device failed (a driver Error) since it was last activated. Kept through
  /// deactivate(), which turns Failed into Inactive, so that whoever ran the session can
  /// still report the failure (the server exits 1).
  bool failed_since_activation() const { return failed_; }

 private:
  std::unique_ptr<Device> dev_;
  Lifecycle state_ = Lifecycle::Unconfigured;
  std::string error_;
  bool failed_ = false;
};

}  // namespace hapticloth::devices
