// The 1 kHz haptic tick (sections 3.4 and 4.1): read the device, map each fingertip into the
// scene (a late tick's motion caught up over the ticks it missed: late_tick.hpp), ask the
// rendering mode's haptic half (SurfaceContact: rendering.hpp) for the force, keep the
// multirate path's models within the energy the hand gave them (energy_bound.hpp) and each
// coupling passive (passivity.hpp), pass the force through the safety gate, write it, render
// the tactile output where the device has a tactile display (tactile_rendering.hpp), and
// report the fingertips and contacts to the simulation. tick() allocates nothing and takes no
// lock.
#pragma once

#include <memory>
#include <vector>

#include <Eigen/Core>

#include "hal/handle.hpp"
#include "hal/rt_handoff.hpp"
#include "hal/safety_gate.hpp"
#include "haptics/modes/energy_bound.hpp"
#include "haptics/sim/handoff.hpp"
#include "haptics/loop/late_tick.hpp"
#include "haptics/modes/params.hpp"
#include "haptics/loop/passivity.hpp"
#include "haptics/modes/surface_contact.hpp"
#include "haptics/loop/stats.hpp"
#include "haptics/loop/tactile_rendering.hpp"

namespace hapticloth::haptics {


/// Device frame -> scene frame: p_scene = origin + R p_device (R a rotation).
struct DeviceMapping {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Vec3 origin = Vec3::Zero();
};

class HapticLoop {
 public:
  /// `contact`: the haptic half of rendering mode `mode` (rendering_modes.hpp).
  HapticLoop(devices::DeviceHandle& device, devices::SafetyGate& gate, const FingerParams& finger,
             const DeviceMapping& map, std::unique_ptr<SurfaceContact> contact, Rendering mode,
             TripleBuffer<ClothSnapshot>& from_sim, TripleBuffer<HapticReport>& to_sim);

  /// Set-up: the tactile half, for a device with a tactile display (none: nothing is spent).
  void attach_tactile(std::unique_ptr<TactileRendering> t) { tactile_ = std::move(t); }
  /// The tactile half, or nullptr.
  const TactileRendering* tactile() const { return tactile_.get(); }
  /// The tactile output the device was sent on the last tick (after the safety gate).
  const devices::TactileCommand& last_tactile() const { return tactile_gated_; }

  /// Before the simulation's first step: reads the device and reports where its fingertips are
  /// (touching nothing, no force sent), so that the first step already has them. Without it the
  /// first global step runs without fingertips, and a free cloth pinched from the first tick
  /// falls through the lower one before the contact first sees it (test_session
  /// PinchEngagedFromTheFirstTickHolds).
  void prime(double now) noexcept;
  /// One tick at loop time `now` (s). Real-time safe.
  void tick(double now) noexcept;
  /// A closing tick: zero force commanded through the safety gate (which slew-limits the way
  /// down). Returns true once the force sent to the device is zero on every finger.
  bool wind_down(double now) noexcept;

  std::uint64_t patch_rebuilds() const { return contact_->patch_rebuilds(); }
  /// Patch builds whose springs were softened to stay stable (PatchParams::max_substeps).
  std::uint64_t patch_softened() const { return contact_->patch_softened(); }
  /// The coupling stiffness in use: the scene's, clamped to the device's max_stiffness.
  double coupling_stiffness() const { return k_; }

  const HapticReport& last_report() const { return report_; }
  const devices::DeviceState& device_state() const { return state_; }
  const devices::DeviceCommand& last_command() const { return gated_; }
  int fingers() const { return fingers_; }
  double period() const { return period_; }  ///< s, the device's nominal tick
  const FingerParams& params() const { return fp_; }
  std::uint64_t device_errors() const { return device_errors_; }
  std::uint64_t contact_ticks() const { return contact_ticks_; }
  /// Ticks on which no finger was within the broad-phase margin of the cloth.
  std::uint64_t ticks_out_of_reach() const { return out_of_reach_; }
  /// Ticks that came more than half a period late (their motion caught up over the missed ticks).
  std::uint64_t late_ticks() const { return late_ticks_; }
  const LateTickCatchUp& catch_up() const { return catch_up_; }
  const CouplingPassivity& passivity() const { return passivity_; }
  /// The multirate path's energy bound (nullptr with direct coupling, whose proxies are solved
  /// with the cloth itself).
  const EnergyBound* energy_bound() const { return bound_.get(); }
  /// The late-tick catch-up and the passivity controller act (the default); off, the observer
  /// still measures (`hapticloth-bench late-ticks` compares both).
  void set_time_guard(bool on) { guard_ = on; }

 private:
  using Presence = std::array<bool, kMaxFingers>;
  Presence presence(double now) const noexcept;
  static void absent(FingerReport& r, const Vec3& centre, const Vec3& velocity) noexcept;
  void count_out_of_reach(const ClothSnapshot& s) noexcept;
  void read_fingertips(double tick_dt, const Presence& present, std::array<Fingertip, kMaxFingers>& tips,
                       std::array<Vec3, kMaxFingers>& measured) noexcept;
  void touch(const ClothSnapshot& s, double now, double tick_dt, const Presence& present,
             const std::array<Fingertip, kMaxFingers>& tips,
             const std::array<Vec3, kMaxFingers>& measured) noexcept;
  void bound_energy(const std::array<Fingertip, kMaxFingers>& tips) noexcept;
  void command(double tick_dt, const Presence& present, const std::array<Fingertip, kMaxFingers>& tips,
               const std::array<Vec3, kMaxFingers>& measured) noexcept;
  void report_felt_forces() noexcept;
  void render_tactile(const ClothSnapshot& s, double now, double tick_dt) noexcept;

  devices::DeviceHandle& dev_;
  devices::SafetyGate& gate_;
  FingerParams fp_;
  double k_;
  DeviceMapping map_;
  TripleBuffer<ClothSnapshot>& in_;
  TripleBuffer<HapticReport>& out_;
  int fingers_;
  double period_;  // s, the device's nominal tick
  devices::DeviceState state_;
  devices::DeviceCommand cmd_, gated_;
  HapticReport report_;
  std::unique_ptr<SurfaceContact> contact_;
  std::unique_ptr<EnergyBound> bound_;  // the multirate path's models only
  std::unique_ptr<TactileRendering> tactile_;  // a device with a tactile display only
  devices::TactileCommand tactile_cmd_, tactile_gated_;
  std::array<Vec3, kMaxFingers> sent_{};  // the forces the device holds since the last tick, scene frame
  LateTickCatchUp catch_up_;
  CouplingPassivity passivity_;
  std::array<Vec3, kMaxFingers> damp_{};  // this tick's passivity damping per finger, scene frame
  bool guard_ = true;
  double last_now_ = -1.0;
  std::uint64_t tick_ = 0, device_errors_ = 0, contact_ticks_ = 0, out_of_reach_ = 0, late_ticks_ = 0;
};

}  // namespace hapticloth::haptics
