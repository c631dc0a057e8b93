// The global cloth's side of the local-patch coupling (section 4.3): each global step takes the
// haptic loop's rendered forces and spreads each over the cloth around its contact point with a
// smooth kernel (so the deformation does not depend on where in a triangle the finger presses:
// the paper's figure 8), the contact spring entering the implicit solve, and transfers the
// impact momentum at contact onset (4.3.2). Direct coupling does not use it (FingertipContact).
#pragma once

#include <array>
#include <vector>

#include "cloth/integrator.hpp"
#include "haptics/handoff.hpp"

namespace hapticloth::haptics {

class KernelCoupling {
 public:
  /// radius: of the kernel, m; finger_mass: effective moving mass of a fingertip and the device,
  /// kg, for the impact (0 turns it off).
  KernelCoupling(const cloth::ClothModel& model, const std::vector<std::array<int, 3>>& tris,
                 int fingers, double radius, double finger_mass);

  /// The report's contacts as external forces and stiffness of the integrator's next step.
  void apply(const HapticReport& r, cloth::ClothState& s, cloth::Integrator& integ);

  /// Impact at contact onset (4.3.2): the fingertip (mass m_e, normal velocity v_e) and the
  /// cloth around the contact point (the kernel's effective mass m_s, normal velocity v_s) move
  /// on together at v_es = (m_e v_e + m_s v_s) / (m_e + m_s): the cloth's normal velocities
  /// change by phi_i (v_es - v_s), phi the kernel shape. Momentum is conserved exactly.
  /// Returns the normal momentum given to the cloth, N s.
  double apply_impact(const FingerReport& c, double finger_mass, cloth::ClothState& s);

  double radius() const { return R_; }
  /// Sum of the contact forces applied to the cloth on the last step, N.
  const Vec3& applied_force() const { return applied_; }

 private:
  const cloth::ClothModel& model_;
  const std::vector<std::array<int, 3>>& tris_;
  int fingers_;
  double R_, finger_mass_;
  std::vector<double> w_;
  std::array<std::uint64_t, kMaxFingers> impacts_seen_{};
  Vec3 applied_ = Vec3::Zero();
};

}  // namespace hapticloth::haptics
