// The global simulation side of the haptic coupling (section 4.3): each step takes the haptic
// loop's latest contacts, spreads each contact force over the cloth around the contact point
// (a smooth kernel a little wider than the fingertip, so the deformation does not depend on
// where in a triangle the finger presses: the paper's figure 8 problem), with the contact
// spring entering the implicit solve, steps the cloth (eqs. 8-9), refits the broad phase, finds
// each finger's candidate triangles and publishes a snapshot for the haptic loop.
#pragma once

#include <memory>

#include "cloth/integrator.hpp"
#include "haptics/broad_phase.hpp"
#include "haptics/handoff.hpp"
#include "haptics/haptic_loop.hpp"
#include "haptics/stats.hpp"
#include "haptics/triple_buffer.hpp"

namespace hapticloth::haptics {

struct CouplingParams {
  /// Radius of the force-spreading kernel, m; 0 = max(fingertip radius, 2 x mean edge).
  double kernel_radius = 0.0;
  /// Effective moving mass of a fingertip and the device, kg, for the impact at contact onset
  /// (4.3.2); 0 turns the impact transfer off.
  double finger_mass = 0.05;
  /// Broad-phase margin beyond the fingertip radius, m (covers motion between two steps).
  double margin = 0.01;
  /// Largest vertex displacement (m) before the hierarchy is refitted; until then queries grow
  /// by the displacement so that they stay conservative.
  double refit_slack = 0.003;
};

class SimWorker {
 public:
  SimWorker(const cloth::ClothModel& model, const cloth::IntegratorConfig& cfg,
            std::unique_ptr<cloth::LinearSolver> solver, const cloth::ClothState& start,
            int fingers, const FingerParams& finger, const CouplingParams& coupling,
            TripleBuffer<ClothSnapshot>& to_haptics, TripleBuffer<HapticReport>& from_haptics);

  /// One global step at loop time `now`; publishes the new snapshot.
  void step(double now);
  /// Publishes the current state without stepping (before the loops start).
  void publish(double now);

  const cloth::ClothState& state() const { return s_; }
  /// The snapshot published by the last step (the sim thread's own copy).
  const ClothSnapshot& last_snapshot() const { return mine_; }
  cloth::ClothState& state_mut() { return s_; }
  const cloth::Integrator& integrator() const { return integ_; }
  double kernel_radius() const { return kernel_r_; }
  const Histogram& step_us() const { return step_us_; }
  std::uint64_t steps() const { return steps_; }
  std::uint64_t refits() const { return refits_; }
  /// Sum of the contact forces applied to the cloth on the last step, N.
  const Vec3& applied_force() const { return applied_; }

  /// Impact at contact onset (4.3.2): the fingertip (mass m_e, normal velocity v_e) and the
  /// cloth around the contact point (the kernel's effective mass m_s, normal velocity v_s) move
  /// on together at v_es = (m_e v_e + m_s v_s) / (m_e + m_s): the cloth's normal velocities
  /// change by phi_i (v_es - v_s), phi the kernel shape. Momentum is conserved exactly.
  /// Returns the normal momentum given to the cloth, N s.
  double apply_impact(const FingerReport& c, double finger_mass);

 private:
  void apply_contacts();
  void find_candidates();
  void vertex_normals();

  const cloth::ClothModel& model_;
  cloth::Integrator integ_;
  cloth::ClothState s_;
  int fingers_;
  FingerParams fp_;
  CouplingParams cp_;
  double kernel_r_;
  BroadPhase bp_;
  TripleBuffer<ClothSnapshot>& out_;
  TripleBuffer<HapticReport>& in_;
  std::vector<std::array<int, 3>> tris_;
  std::vector<Vec3> normals_;
  std::vector<double> w_;
  ClothSnapshot mine_;
  std::vector<Vec3> x_refit_;  // positions at the last refit
  std::uint64_t refits_ = 0;
  std::array<std::uint64_t, kMaxFingers> impacts_seen_{};
  Vec3 applied_ = Vec3::Zero();
  Histogram step_us_;
  std::uint64_t steps_ = 0;
};

}  // namespace hapticloth::haptics
