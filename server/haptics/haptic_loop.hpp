// The 1 kHz haptic tick (sections 3.4 and 4.1): read the device, find each fingertip's contact
// with the cloth (exact sphere-triangle test on the broad phase's candidates, with the cloth
// extrapolated at constant velocity from the last global step), move a god-object proxy per
// finger on the cloth surface with Coulomb friction, render a spring-damper force from the
// proxy offset with shaded normals (4.1.2), pass it through the safety gate, write it, and
// report contacts to the simulation. tick() allocates nothing and takes no lock.
#pragma once

#include <memory>
#include <vector>

#include <Eigen/Core>

#include "hal/handle.hpp"
#include "hal/safety_gate.hpp"
#include "haptics/handoff.hpp"
#include "haptics/local_patch.hpp"
#include "haptics/stats.hpp"
#include "haptics/triple_buffer.hpp"

namespace hapticloth::haptics {

struct FingerParams {
  double radius = 0.008;     ///< m, fingertip sphere
  double stiffness = 800.0;  ///< N/m, proxy spring (clamped to the device's max_stiffness)
  double damping = 1.0;      ///< N s/m, along the contact normal
  double friction = 0.5;     ///< Coulomb coefficient (stick and slip)
};

/// Device frame -> scene frame: p_scene = origin + R p_device (R a rotation).
struct DeviceMapping {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Vec3 origin = Vec3::Zero();
};

class HapticLoop {
 public:
  HapticLoop(const std::vector<std::array<int, 3>>& triangles, int vertices,
             devices::DeviceHandle& device, devices::SafetyGate& gate, const FingerParams& finger,
             const DeviceMapping& map, TripleBuffer<ClothSnapshot>& from_sim,
             TripleBuffer<HapticReport>& to_sim);

  /// One tick at loop time `now` (s). Real-time safe.
  void tick(double now) noexcept;

  /// Local refinement (4.2): a subdivided patch per fingertip simulated at the haptic rate.
  /// Set-up only (allocates the patches).
  void enable_local_patch(const std::vector<Vec3>& rest, const std::vector<char>& pinned,
                          const PatchParams& p);
  bool local_patch() const { return !patch_.empty(); }
  /// Without local patches: extrapolate the cloth at constant velocity between global steps
  /// (default), or hold the last global state (the naive coupling, for comparison).
  void set_extrapolation(bool on) { extrapolate_ = on; }
  std::uint64_t patch_rebuilds() const { return rebuilds_; }
  /// Patch builds whose springs were softened to stay stable (PatchParams::max_substeps).
  std::uint64_t patch_softened() const { return softened_; }

  const HapticReport& last_report() const { return report_; }
  const devices::DeviceState& device_state() const { return state_; }
  const devices::DeviceCommand& last_command() const { return gated_; }
  int fingers() const { return fingers_; }
  const FingerParams& params() const { return fp_; }
  std::uint64_t device_errors() const { return device_errors_; }
  std::uint64_t candidate_overflows() const { return overflows_; }
  std::uint64_t contact_ticks() const { return contact_ticks_; }
  /// Ticks that skipped the narrow phase because no finger had a candidate triangle.
  std::uint64_t narrow_phase_skipped() const { return np_skipped_; }

 private:
  struct Proxy {
    bool contact = false;
    int side = 0;             // which side of the cloth the finger is on (+1 along the normal)
    Vec3 anchor = Vec3::Zero();  // friction anchor on the surface (sticks, slides when slipping)
  };
  void finger_contact(int f, double now, double tick_dt, const Vec3& c, const Vec3& vc,
                      FingerReport& out) noexcept;

  const std::vector<std::array<int, 3>>& tris_;
  devices::DeviceHandle& dev_;
  devices::SafetyGate& gate_;
  FingerParams fp_;
  double k_;
  DeviceMapping map_;
  TripleBuffer<ClothSnapshot>& in_;
  TripleBuffer<HapticReport>& out_;
  int fingers_;
  devices::DeviceState state_;
  devices::DeviceCommand cmd_, gated_;
  HapticReport report_;
  std::array<Proxy, kMaxFingers> proxy_{};
  std::vector<std::unique_ptr<LocalPatch>> patch_;
  bool extrapolate_ = true;
  std::array<std::uint64_t, kMaxFingers> impacts_{};
  std::uint64_t rebuilds_ = 0, softened_ = 0;
  double last_now_ = -1.0;
  std::uint64_t tick_ = 0, device_errors_ = 0, overflows_ = 0, contact_ticks_ = 0, np_skipped_ = 0;
};

}  // namespace hapticloth::haptics
