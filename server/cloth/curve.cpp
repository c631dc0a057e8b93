#include "cloth/curve.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace hapticloth::cloth {

void StrainStressCurve::evaluate(double eps, double& sigma, double& dsigma) const {
  double psi;
  evaluate_all(eps, psi, sigma, dsigma);
}

double StrainStressCurve::stress(double eps) const {
  double s, ds;
  evaluate(eps, s, ds);
  return s;
}

double StrainStressCurve::stiffness(double eps) const {
  double s, ds;
  evaluate(eps, s, ds);
  return ds;
}

double StrainStressCurve::energy(double eps) const {
  double psi, sg, ds;
  evaluate_all(eps, psi, sg, ds);
  return psi;
}

void StrainStressCurve::validate(const std::string& what, double max_strain) const {
  auto fail = [&](const std::string& msg) {
    throw std::invalid_argument(what.empty() ? msg : what + ": " + msg);
  };
  if (segments < 1 || segments > 3) fail("between 1 and 3 segments are allowed (appendix A.2)");
  if (knots[0] != 0.0) fail("the first knot E_0 must be 0");
  for (int i = 1; i < segments; ++i) {
    if (!std::isfinite(knots[i]) || !(knots[i] > knots[i - 1])) {
      std::ostringstream os;
      os << "knots must be finite and strictly increasing (knot " << i << " = " << knots[i] << ")";
      fail(os.str());
    }
  }
  for (int i = 0; i < segments; ++i) {
    for (int j = 0; j < 4; ++j) {
      if (!std::isfinite(B[i][j])) fail("coefficient B[" + std::to_string(i) + "][" + std::to_string(j) + "] is not finite");
    }
    if (i >= 1 && (B[i][0] != 0.0 || B[i][1] != 0.0)) {
      fail("B[" + std::to_string(i) + "][0] and B[" + std::to_string(i) +
           "][1] must be 0 so that the curve is C1 at knot " + std::to_string(i));
    }
  }
  if (odd && B[0][0] != 0.0) fail("an odd (shear) curve needs B[0][0] = 0");
  if (!std::isfinite(viscosity) || viscosity < 0.0) fail("viscosity must be finite and >= 0");
  if (!std::isfinite(compression_scale) || compression_scale < 0.0)
    fail("compression_scale must be finite and >= 0");
  // A negative tangent would make the stiffness matrix indefinite and the material unstable.
  const int n = 400;
  for (int k = 0; k <= n; ++k) {
    const double e = max_strain * k / n;
    if (stiffness(e) < 0.0) {
      std::ostringstream os;
      os << "the tangent d sigma/d eps is negative (" << stiffness(e) << " N/m) at strain " << e
         << "; a material law must be non-decreasing up to strain " << max_strain;
      fail(os.str());
    }
  }
  if (B[0][1] < 0.0) fail("the initial slope B[0][1] must be >= 0");
}

StrainStressCurve StrainStressCurve::linear(double k, bool is_odd) {
  StrainStressCurve c;
  c.segments = 1;
  c.B[0] = {0.0, k, 0.0, 0.0};
  c.odd = is_odd;
  return c;
}

}  // namespace hapticloth::cloth
