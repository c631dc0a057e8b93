// The simulation half of the patch model (rendering.hpp; section 4.3): each global step takes
// the haptic loop's rendered forces and spreads each over the cloth around its contact point
// with a smooth kernel (so the deformation does not depend on where in a triangle the finger
// presses: the paper's figure 8), the contact spring entering the implicit solve, and transfers
// the impact momentum at contact onset (4.3.2). Each snapshot lists, per finger, the triangles a
// patch around the fingertip can take (ClothSnapshot::near_triangles), so the haptic thread's
// patch builds cost what the patch holds, not what the mesh holds.
#pragma once

#include <array>
#include <vector>

#include "cloth/integrator.hpp"
#include "haptics/sim/handoff.hpp"
#include "haptics/modes/sim_coupling.hpp"

namespace hapticloth::haptics {

class KernelCoupling final : public SimCoupling {
 public:
  /// radius: of the kernel, m; finger_mass: effective moving mass of a fingertip and the device,
  /// kg, for the impact (0 turns it off); patch_radius: of the patches the haptic loop builds,
  /// m; margin: the contact's reach beyond the fingertip, m.
  KernelCoupling(const cloth::ClothModel& model, cloth::Integrator& integ, int fingers,
                 double radius, double finger_mass, double patch_radius, double margin);

  void couple(const HapticReport& r, double, cloth::ClothState& s) override { apply(r, s, integ_); }
  void conclude(const cloth::ClothState&) override {}
  void fill(const HapticReport& r, const cloth::ClothState& s, ClothSnapshot& snap) override;
  std::uint64_t patch_candidate_overflows() const override { return overflows_; }

  /// The report's contacts as external forces and stiffness of the integrator's next step.
  void apply(const HapticReport& r, cloth::ClothState& s, cloth::Integrator& integ);

  /// Impact at contact onset (4.3.2): the fingertip (mass m_e, normal velocity v_e) and the
  /// cloth around the contact point (the kernel's effective mass m_s, normal velocity v_s) move
  /// on together at v_es = (m_e v_e + m_s v_s) / (m_e + m_s): the cloth's normal velocities
  /// change by phi_i (v_es - v_s), phi the kernel shape. Momentum is conserved exactly.
  /// Returns the normal momentum given to the cloth, N s.
  double apply_impact(const FingerReport& c, double finger_mass, cloth::ClothState& s);

  double radius() const { return R_; }

 private:
  void list_patch_candidates(const HapticReport& r, const cloth::ClothState& s, ClothSnapshot& snap);

  const cloth::ClothModel& model_;
  cloth::Integrator& integ_;
  const std::vector<std::array<int, 3>>& tris_;
  int fingers_;
  double R_, finger_mass_, patch_radius_, margin_;
  std::uint64_t overflows_ = 0;
  std::vector<double> w_;
  std::array<std::uint64_t, kMaxFingers> impacts_seen_{};
};

}  // namespace hapticloth::haptics
