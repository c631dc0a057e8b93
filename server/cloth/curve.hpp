// Strain-stress material law of one weave direction (paper section 3.2, appendix A.2).
#pragma once

#include <array>
#include <string>

namespace hapticloth::cloth {

/// C1 truncated power spline (appendix A.2):
///   sigma(eps) = sum_i sum_j B_ij (eps - E_i)_+^j,  j <= 3, i < 3, E_0 = 0,
///   B_i0 = B_i1 = 0 for i >= 1 (C1 continuity at the inner knots).
/// Units: eps dimensionless (shear: radians for small angles), sigma in N/m.
///
/// Below zero strain a tensile curve (odd == false) continues linearly with the
/// initial slope B_01 (the paper's "A eps" term), scaled by `compression_scale`,
/// so the law is C1 at eps = 0. A shear curve (odd == true) is odd:
/// sigma(-eps) = -sigma(eps), which requires B_00 = 0.
///
/// Evaluation is allocation-free and branch-light; all members are plain values.
struct StrainStressCurve {
  int segments = 1;                       ///< number of spline segments, 1..3
  std::array<double, 3> knots{0, 0, 0};   ///< E_i; knots[0] == 0, strictly increasing
  std::array<std::array<double, 4>, 3> B{};  ///< B[i][j] in N/m
  bool odd = false;                       ///< shear curves are odd functions of strain
  double compression_scale = 1.0;         ///< slope factor for eps < 0 (tensile curves)
  double viscosity = 0.0;                 ///< linear viscosity eta, sigma_v = eta * eps' (N s/m)
  double max_strain = 0.3;                ///< largest strain the law was fitted/validated for

  /// Stress sigma(eps) in N/m.
  double stress(double eps) const;
  /// Tangent d sigma / d eps in N/m.
  double stiffness(double eps) const;
  /// Stress and tangent together (one pass).
  void evaluate(double eps, double& sigma, double& dsigma) const;
  /// Strain energy density Psi(eps) = integral_0^eps sigma, in J/m^2 (Psi' = sigma).
  double energy(double eps) const;

  /// Throws std::invalid_argument naming `what` if the curve breaks an invariant
  /// (knot order, C1 constraints, non-finite values, odd curve with B_00 != 0,
  /// negative tangent on [0, max_strain]).
  void validate(const std::string& what, double max_strain) const;

  /// Linear law sigma = k eps (used by tests and simple scenes).
  static StrainStressCurve linear(double k, bool odd = false);
};

}  // namespace hapticloth::cloth
