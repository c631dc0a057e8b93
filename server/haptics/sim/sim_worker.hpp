// The global simulation (section 4.3): each step takes the haptic loop's latest fingertips,
// couples them to the cloth through the rendering mode's simulation half (SimCoupling:
// rendering.hpp), steps the cloth (eqs. 8-9) and publishes a snapshot for the haptic loop.
#pragma once

#include <memory>

#include "cloth/integrator.hpp"
#include "haptics/contact/fingertip_contact.hpp"
#include "haptics/sim/handoff.hpp"
#include "haptics/modes/local_patch.hpp"
#include "haptics/refinement/local_refinement.hpp"
#include "haptics/modes/params.hpp"
#include "haptics/modes/rendering.hpp"
#include "haptics/modes/sim_coupling.hpp"
#include "haptics/loop/stats.hpp"
#include "hal/rt_handoff.hpp"

namespace hapticloth::haptics {

class SimWorker {
 public:
  /// `mode`: the rendering mode whose simulation half couples the fingertips to each step
  /// (rendering_modes.hpp); `patch`: the patch model's patches (that mode only).
  SimWorker(const cloth::ClothModel& model, const cloth::IntegratorConfig& cfg,
            std::unique_ptr<cloth::LinearSolver> solver, const cloth::ClothState& start,
            int fingers, const FingerParams& finger, const CouplingParams& coupling,
            Rendering mode, const PatchParams& patch, TripleBuffer<ClothSnapshot>& to_haptics,
            TripleBuffer<HapticReport>& from_haptics);

  /// One global step at loop time `now`; publishes the new snapshot.
  void step(double now);
  /// Publishes the current state without stepping (before the loops start).
  void publish(double now);

  const cloth::ClothState& state() const { return s_; }
  /// The snapshot published by the last step (the sim thread's own copy).
  const ClothSnapshot& last_snapshot() const { return last_snapshot_; }
  const cloth::Integrator& integrator() const { return integ_; }
  /// The proxies' contact (nullptr with the patch model).
  const FingertipContact* fingertips() const { return coupling_->fingertips(); }
  /// The local refinement (nullptr when off, with the patch model, or when the global mesh
  /// resolves the contact patch).
  const RefinementSchedule* refinement() const { return coupling_->refinement(); }
  /// From now on, settle the local refinement beside the steps (a real-time session).
  void refine_beside_steps() { coupling_->refine_beside_steps(); }
  /// Snapshots in which a finger had more patch candidates than their room (the patch was
  /// built from the first ones, in index order).
  std::uint64_t patch_candidate_overflows() const { return coupling_->patch_candidate_overflows(); }
  const Histogram& step_us() const { return step_us_; }
  /// The last step's time, us (what step_us() last took in).
  double last_step_us() const { return last_step_us_; }
  /// Per step, the time the step waited for the integrator's helper thread (two threads): what
  /// a slowed helper core adds to step_us.
  const Histogram& helper_wait_us() const { return helper_wait_us_; }
  std::uint64_t steps() const { return steps_; }

 private:
  void mark_near(const HapticReport& r, ClothSnapshot& snap) const;

  cloth::Integrator integ_;
  cloth::ClothState s_;
  int fingers_;
  double reach_;  // m: a fingertip is near the cloth within this of its bounding box
  TripleBuffer<ClothSnapshot>& out_;
  TripleBuffer<HapticReport>& in_;
  std::unique_ptr<SimCoupling> coupling_;
  ClothSnapshot last_snapshot_;  // the last step's snapshot, as published
  Histogram step_us_, helper_wait_us_;
  double last_step_us_ = 0.0;
  std::uint64_t steps_ = 0;
};

}  // namespace hapticloth::haptics
