// Observers of a running session (publishers, loggers). Called on the loops' own threads, so an
// observer must return quickly, never block and never allocate in on_haptic_tick (it runs on
// the 1 kHz path): copy into a preallocated mailbox and let its own thread do the rest.
#pragma once

#include "hal/device.hpp"
#include "haptics/sim/handoff.hpp"
#include "haptics/refinement/refined_regions.hpp"
#include "haptics/loop/stats.hpp"
#include "haptics/loop/tactile_rendering.hpp"

namespace hapticloth::haptics {

class SessionObserver {
 public:
  virtual ~SessionObserver() = default;
  /// Simulation thread, after every global step (the snapshot the haptic loop will see).
  virtual void on_sim_step(const ClothSnapshot&) noexcept {}
  /// Simulation thread, before on_sim_step, when the local refinement's children changed
  /// (settled, built or dropped) since the last call: what a viewer draws of them.
  virtual void on_refined(const RefinedRegions&) noexcept {}
  /// Haptic thread, after every tick: the contacts, the raw device state and the gated command.
  virtual void on_haptic_tick(const HapticReport&, const devices::DeviceState&,
                              const devices::DeviceCommand&) noexcept {}
  /// Haptic thread, after on_haptic_tick, on a device with a tactile display: where each finger
  /// is on the fabric and the tactile output the device was sent.
  virtual void on_tactile(const HapticReport&, const TactileRendering&, const devices::TactileCommand&) noexcept {}
  /// Haptic thread, about once a second: the loop statistics so far.
  virtual void on_loop_stats(const LoopStats&) noexcept {}
};

}  // namespace hapticloth::haptics
