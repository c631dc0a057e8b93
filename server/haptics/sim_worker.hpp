// The global simulation side of the haptic coupling (section 4.3): each step takes the haptic
// loop's latest fingertips, couples them to the cloth (direct coupling and the response model:
// the fingertip proxies solved with the cloth in its implicit step, FingertipContact; the patch
// model: the rendered forces spread over the cloth, KernelCoupling), steps the cloth (eqs. 8-9)
// and publishes a snapshot for the haptic loop (with the response model, the step's linear
// response to the fingertips too).
#pragma once

#include <memory>

#include "cloth/integrator.hpp"
#include "haptics/fingertip_contact.hpp"
#include "haptics/handoff.hpp"
#include "haptics/haptic_loop.hpp"
#include "haptics/kernel_coupling.hpp"
#include "haptics/local_refinement.hpp"
#include "haptics/stats.hpp"
#include "haptics/surface_contact.hpp"
#include "hal/rt_handoff.hpp"

namespace hapticloth::haptics {

struct CouplingParams {
  /// Local refinement only: radius of the force-spreading kernel, m; 0 = max(fingertip radius,
  /// 2 x mean edge).
  double kernel_radius = 0.0;
  /// Local refinement only: effective moving mass of a fingertip and the device, kg, for the
  /// impact at contact onset (4.3.2); 0 turns the impact transfer off.
  double finger_mass = 0.05;
  /// Reach beyond the fingertip radius, m, within which the cloth is searched for contacts.
  double margin = 0.01;
  /// Local refinement under the fingertips (direct coupling and the response model;
  /// LocalRefinement): children where the global mesh does not resolve the contact patch.
  Refine refine = Refine::Auto;
  RefinementParams refinement{};
};

class SimWorker {
 public:
  /// `mode`: Direct and Response solve the fingertip proxies with the cloth (Response also
  /// hands the haptic loop the step's response, cloth::Integrator::proxy_response); Patch
  /// spreads the forces of the haptic loop's local patches over the cloth (KernelCoupling).
  SimWorker(const cloth::ClothModel& model, const cloth::IntegratorConfig& cfg,
            std::unique_ptr<cloth::LinearSolver> solver, const cloth::ClothState& start,
            int fingers, const FingerParams& finger, const CouplingParams& coupling,
            Rendering mode, TripleBuffer<ClothSnapshot>& to_haptics,
            TripleBuffer<HapticReport>& from_haptics);

  /// One global step at loop time `now`; publishes the new snapshot.
  void step(double now);
  /// Publishes the current state without stepping (before the loops start).
  void publish(double now);

  const cloth::ClothState& state() const { return s_; }
  /// The snapshot published by the last step (the sim thread's own copy).
  const ClothSnapshot& last_snapshot() const { return mine_; }
  cloth::ClothState& state_mut() { return s_; }
  const cloth::Integrator& integrator() const { return integ_; }
  /// Direct coupling's contact (nullptr with local patches).
  const FingertipContact* fingertips() const { return tips_.get(); }
  /// The local refinement (nullptr when off, with the patch model, or when the global mesh
  /// resolves the contact patch).
  const LocalRefinement* refinement() const { return refine_.get(); }
  double kernel_radius() const { return kernel_r_; }
  /// The patch model's radius (0: no patch model): each snapshot then lists, per finger, the
  /// triangles a patch around the fingertip can take (ClothSnapshot::near_triangles).
  void set_patch_radius(double radius) { patch_radius_ = radius; }
  /// Snapshots in which a finger had more patch candidates than their room (the patch was
  /// built from the first ones, in index order).
  std::uint64_t patch_candidate_overflows() const { return patch_overflows_; }
  const Histogram& step_us() const { return step_us_; }
  /// The last step's time, us (what step_us() last took in).
  double last_step_us() const { return last_step_us_; }
  /// Per step, the time the step waited for the integrator's helper thread (two threads): what
  /// a slowed helper core adds to step_us.
  const Histogram& helper_wait_us() const { return helper_wait_us_; }
  std::uint64_t steps() const { return steps_; }
  /// Sum of the contact forces on the cloth in the last step, N.
  Vec3 applied_force() const;

 private:
  std::array<FingerTarget, kMaxFingers> fingertip_targets(const HapticReport& r, double now) const;
  void mark_near(const HapticReport& r);
  void mark_patch_candidates(const HapticReport& r, ClothSnapshot& snap);
  void hand_over_response();

  const cloth::ClothModel& model_;
  cloth::Integrator integ_;
  cloth::ClothState s_;
  int fingers_;
  FingerParams fp_;
  CouplingParams cp_;
  double kernel_r_;
  TripleBuffer<ClothSnapshot>& out_;
  TripleBuffer<HapticReport>& in_;
  const std::vector<std::array<int, 3>>& tris_;  // the model's
  std::unique_ptr<FingertipContact> tips_;
  std::unique_ptr<KernelCoupling> kernel_;
  std::unique_ptr<LocalRefinement> refine_;
  bool response_on_ = false;
  std::vector<cloth::Mat3> response_;
  ClothSnapshot mine_;
  Histogram step_us_, helper_wait_us_;
  double last_step_us_ = 0.0;
  std::uint64_t steps_ = 0;
  double patch_radius_ = 0.0;
  std::uint64_t patch_overflows_ = 0;
};

}  // namespace hapticloth::haptics
