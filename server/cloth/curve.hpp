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
  /// Largest strain the law was fitted and validated for. Beyond it (|eps| > max_strain) the
  /// law continues linearly with its tangent there (C1), so that a cubic fitted to data never
  /// turns down outside the data.
  double max_strain = 0.3;

  /// Stress sigma(eps) in N/m.
  double stress(double eps) const;
  /// Tangent d sigma / d eps in N/m.
  double stiffness(double eps) const;
  /// Stress and tangent together (one pass).
  void evaluate(double eps, double& sigma, double& dsigma) const;
  /// Strain energy density Psi(eps) = integral_0^eps sigma, in J/m^2 (Psi' = sigma).
  double energy(double eps) const;
  /// Psi, sigma and d sigma / d eps in one pass (inline: the assembly calls it per element).
  inline void evaluate_all(double eps, double& psi, double& sigma, double& dsigma) const;

  /// Throws std::invalid_argument naming `what` if the curve breaks an invariant
  /// (knot order, C1 constraints, non-finite values, odd curve with B_00 != 0,
  /// negative tangent on [0, max_strain]).
  void validate(const std::string& what, double max_strain) const;

  /// Linear law sigma = k eps (used by tests and simple scenes).
  static StrainStressCurve linear(double k, bool odd = false);
};

namespace detail {
// The spline proper for e >= 0 (appendix A.2): Psi, sigma, d sigma / d eps. T is double, or
// lanes of doubles (cloth/element_lanes: a GCC vector, whose comparisons and ?: go lane by
// lane). A segment adds nothing where e is below its knot.
template <class T>
inline void spline_all(const StrainStressCurve& c, T e, T& psi, T& s, T& ds) {
  const auto& b0 = c.B[0];
  s = b0[0] + e * (b0[1] + e * (b0[2] + e * b0[3]));
  ds = b0[1] + e * (2.0 * b0[2] + 3.0 * e * b0[3]);
  psi = e * (b0[0] + e * (0.5 * b0[1] + e * (b0[2] * (1.0 / 3.0) + 0.25 * e * b0[3])));
  for (int i = 1; i < c.segments; ++i) {
    const T past = e - c.knots[i];
    const T d = past > T{} ? past : T{};
    const auto& bi = c.B[i];
    s += d * d * (bi[2] + d * bi[3]);
    ds += d * (2.0 * bi[2] + 3.0 * d * bi[3]);
    psi += d * d * d * (bi[2] * (1.0 / 3.0) + 0.25 * d * bi[3]);
  }
}
}  // namespace detail

inline void StrainStressCurve::evaluate_all(double eps, double& psi, double& s, double& ds) const {
  double e = eps, sign = 1.0;
  if (eps < 0.0) {
    if (!odd) {  // tensile law below zero strain: linear, the "A eps" term, scaled
      const double k = compression_scale * B[0][1];
      s = B[0][0] + k * eps;
      ds = k;
      psi = eps * (B[0][0] + 0.5 * k * eps);
      return;
    }
    e = -eps;
    sign = -1.0;
  }
  if (e <= max_strain) {
    detail::spline_all<double>(*this, e, psi, s, ds);
  } else {  // linear continuation beyond the validated range (C1)
    double pm, sm, km;
    detail::spline_all<double>(*this, max_strain, pm, sm, km);
    const double d = e - max_strain;
    s = sm + km * d;
    ds = km;
    psi = pm + d * (sm + 0.5 * km * d);
  }
  s *= sign;  // odd law: the tangent and the energy are even
}

}  // namespace hapticloth::cloth
