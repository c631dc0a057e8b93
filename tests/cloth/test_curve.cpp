// Material laws: the C1 truncated power spline of appendix A.2.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "cloth/curve.hpp"
#include "support/alloc_counter.hpp"
#include "support/fixtures.hpp"

using hapticloth::cloth::StrainStressCurve;

namespace {

StrainStressCurve three_segments() {
  StrainStressCurve c;
  c.segments = 3;
  c.knots = {0.0, 0.05, 0.15};
  c.B[0] = {0.0, 300.0, 500.0, 100.0};
  c.B[1] = {0.0, 0.0, 2000.0, -1000.0};
  c.B[2] = {0.0, 0.0, 8000.0, 20000.0};
  return c;
}

// Reference evaluation straight from the formula sum_i sum_j B_ij (eps - E_i)_+^j.
double reference_stress(const StrainStressCurve& c, double e) {
  double s = 0.0;
  for (int i = 0; i < c.segments; ++i) {
    const double d = e - c.knots[i];
    if (d < 0.0) continue;
    for (int j = 0; j < 4; ++j) s += c.B[i][j] * std::pow(d, j);
  }
  return s;
}

}  // namespace

TEST(Curve, MatchesTruncatedPowerFormula) {
  const auto c = three_segments();
  for (double e = 0.0; e <= 0.3; e += 0.0071)
    EXPECT_NEAR(c.stress(e), reference_stress(c, e), 1e-10 * (1.0 + std::abs(c.stress(e)))) << e;
}

TEST(Curve, IsC1AtEveryKnot) {
  const auto c = three_segments();
  for (double E : {0.0, 0.05, 0.15}) {
    const double h = 1e-9;
    EXPECT_NEAR(c.stress(E - h), c.stress(E + h), 1e-5) << "value jump at knot " << E;
    EXPECT_NEAR(c.stiffness(E - h), c.stiffness(E + h), 1e-3) << "slope jump at knot " << E;
  }
}

TEST(Curve, TangentAndEnergyDerivativesMatchFiniteDifferences) {
  for (const auto& c : {three_segments(), hapticloth::test::denim().weft,
                        hapticloth::test::denim().shear}) {
    for (double e = -0.2; e <= 0.3; e += 0.0123) {
      const double h = 1e-6;
      const double ds_fd = (c.stress(e + h) - c.stress(e - h)) / (2 * h);
      const double dpsi_fd = (c.energy(e + h) - c.energy(e - h)) / (2 * h);
      EXPECT_NEAR(c.stiffness(e), ds_fd, 1e-6 * (1 + std::abs(ds_fd))) << e;
      EXPECT_NEAR(c.stress(e), dpsi_fd, 1e-6 * (1 + std::abs(dpsi_fd))) << e;
    }
  }
}

TEST(Curve, ShearIsOddAndEnergyEven) {
  const auto c = hapticloth::test::denim().shear;
  for (double e : {0.001, 0.05, 0.14, 0.4}) {
    EXPECT_DOUBLE_EQ(c.stress(-e), -c.stress(e));
    EXPECT_DOUBLE_EQ(c.stiffness(-e), c.stiffness(e));
    EXPECT_DOUBLE_EQ(c.energy(-e), c.energy(e));
  }
}

TEST(Curve, CompressionContinuesWithInitialSlope) {
  auto c = hapticloth::test::denim().weft;
  EXPECT_DOUBLE_EQ(c.stress(-0.1), -0.1 * 399.4);
  c.compression_scale = 0.1;
  EXPECT_DOUBLE_EQ(c.stress(-0.1), -0.1 * 39.94);
  EXPECT_DOUBLE_EQ(c.stiffness(-0.1), 39.94);
}

TEST(Curve, ValidationRejectsBrokenLaws) {
  auto expect_invalid = [](StrainStressCurve c, const char* needle) {
    try {
      c.validate("weft", 0.3);
      FAIL() << "accepted a curve that should fail with: " << needle;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("weft"), std::string::npos) << e.what();
    }
  };
  auto c = three_segments();
  EXPECT_NO_THROW(c.validate("weft", 0.3));
  auto bad = c;
  bad.B[1][1] = 5.0;
  expect_invalid(bad, "C1");
  bad = c;
  bad.knots[2] = 0.01;
  expect_invalid(bad, "increasing");
  bad = c;
  bad.B[0] = {0.0, 100.0, -2000.0, 0.0};
  expect_invalid(bad, "negative");
  bad = c;
  bad.odd = true;
  bad.B[0][0] = 1.0;
  expect_invalid(bad, "odd");
  bad = c;
  bad.segments = 4;
  expect_invalid(bad, "segments");
}

TEST(Curve, EvaluationAllocatesNothing) {
  const auto c = three_segments();
  double acc = 0.0;
  hapticloth::test::AllocationGuard guard;
  for (int k = 0; k < 1000; ++k) {
    double s, ds;
    c.evaluate(-0.1 + 0.0004 * k, s, ds);
    acc += s + ds + c.energy(0.0003 * k);
  }
  EXPECT_EQ(guard.count(), 0u);
  EXPECT_TRUE(std::isfinite(acc));
}

// Beyond max_strain the law continues linearly with its tangent there (C1), so a cubic fitted
// to data that would turn down outside the data stays monotone; energy stays consistent.
TEST(Curve, LinearContinuationBeyondMaxStrain) {
  namespace cloth = hapticloth::cloth;
  cloth::StrainStressCurve c;
  c.segments = 2;
  c.knots = {0.0, 0.07, 0.0};
  c.B[0] = {0.0, 3981.5, 8727.7, -15783.8};
  c.B[1] = {0.0, 0.0, 31219.5, -822659.4};  // turns down past ~0.1 if extended as a cubic
  c.max_strain = 0.1;
  double s_m, k_m;
  c.evaluate(0.1, s_m, k_m);
  EXPECT_GT(k_m, 0.0);
  for (double e : {0.12, 0.2, 0.5}) {
    double s, k;
    c.evaluate(e, s, k);
    EXPECT_NEAR(s, s_m + k_m * (e - 0.1), 1e-9 * s);
    EXPECT_DOUBLE_EQ(k, k_m);
    // Psi' = sigma across the junction, by central differences
    const double h = 1e-6;
    EXPECT_NEAR((c.energy(e + h) - c.energy(e - h)) / (2 * h), s, 1e-6 * s);
  }
  // continuity at max_strain
  double s1, k1;
  c.evaluate(0.1 + 1e-12, s1, k1);
  EXPECT_NEAR(s1, s_m, 1e-6);
  EXPECT_NEAR(k1, k_m, 1e-3);
  // odd laws continue on both sides
  c.odd = true;
  c.B[0][0] = 0.0;
  double sp, sn, kp, kn;
  c.evaluate(0.3, sp, kp);
  c.evaluate(-0.3, sn, kn);
  EXPECT_DOUBLE_EQ(sp, -sn);
  EXPECT_DOUBLE_EQ(kp, kn);
}
