// The exact sphere-into-pre-tensioned-membrane reference (support/membrane_reference.hpp).
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "support/membrane_reference.hpp"

using hapticloth::test::IndentSolution;
using hapticloth::test::MembraneDrum;
using hapticloth::test::pre_tension;
using hapticloth::test::small_slope_force;
using hapticloth::test::sphere_indentation;
using hapticloth::test::sphere_indentation_solution;

TEST(MembraneReference, SmallDepthMatchesTheSmallSlopeFormula) {
  const MembraneDrum d;
  const double depth = 0.05e-3;
  const double F = sphere_indentation(d, depth).force;
  const double Fs = small_slope_force(d, depth);
  EXPECT_NEAR(F / Fs, 1.0, 5e-3);
  // and the contact radius, a^2 = F rho / (2 pi T)
  const double a = std::sqrt(Fs * d.sphere_radius / (2.0 * M_PI * pre_tension(d)));
  EXPECT_NEAR(sphere_indentation(d, depth).contact_radius / a, 1.0, 5e-3);
}

TEST(MembraneReference, SmallSlopeFormulaIsAFewPercentLowAtMillimetreDepths) {
  // Tabulated values (default drum), converged to better than 1e-9 relative.
  const MembraneDrum d;
  const double depth[3] = {1e-3, 2e-3, 3e-3};
  const double force[3] = {0.1185365, 0.2602396, 0.4159479};
  const double radius[3] = {1.256228e-3, 1.810727e-3, 2.227158e-3};
  for (int i = 0; i < 3; ++i) {
    const auto r = sphere_indentation(d, depth[i]);
    EXPECT_NEAR(r.force / force[i], 1.0, 1e-6) << depth[i];
    EXPECT_NEAR(r.contact_radius / radius[i], 1.0, 1e-6) << depth[i];
    const double low = 1.0 - small_slope_force(d, depth[i]) / r.force;
    EXPECT_GT(low, 0.005) << depth[i];
    EXPECT_LT(low, 0.03) << depth[i];
  }
}

TEST(MembraneReference, ForceAndContactRadiusIncreaseWithDepth) {
  const MembraneDrum d;
  double F = 0.0, a = 0.0;
  for (double depth = 0.25e-3; depth <= 4e-3; depth += 0.25e-3) {
    const auto r = sphere_indentation(d, depth);
    EXPECT_GT(r.force, F) << depth;
    EXPECT_GT(r.contact_radius, a) << depth;
    F = r.force;
    a = r.contact_radius;
  }
}

TEST(MembraneReference, FlatStretchedMembraneCarriesNoLoad) {
  const MembraneDrum d;
  const IndentSolution s = sphere_indentation_solution(d, 0.0);
  EXPECT_EQ(s.force, 0.0);
  EXPECT_EQ(s.contact_radius, 0.0);
  EXPECT_NEAR(s.centre_stretch, d.prestretch, 1e-12);
  EXPECT_NEAR(s.energy_change, 0.0, 1e-12);  // J; the pre-stretched energy is 0.26 J
  EXPECT_EQ(sphere_indentation(d, 0.0).force, 0.0);
  EXPECT_EQ(small_slope_force(d, 0.0), 0.0);
}

TEST(MembraneReference, IndependentOfTheIntegrationStep) {
  const MembraneDrum d;
  for (double depth : {0.05e-3, 1e-3, 3e-3}) {
    const IndentSolution a = sphere_indentation_solution(d, depth, 1000);
    const IndentSolution b = sphere_indentation_solution(d, depth, 2000);
    EXPECT_NEAR(b.force / a.force, 1.0, 1e-6) << depth;
    EXPECT_NEAR(b.contact_radius / a.contact_radius, 1.0, 1e-6) << depth;
  }
}

// Independent: dE/d(depth) = F for a rigid frictionless indenter and a pinned rim. F comes from
// the membrane tension at the contact edge, E from the strain energy over the whole disc.
TEST(MembraneReference, ForceIsTheDerivativeOfTheElasticEnergy) {
  const MembraneDrum d;
  for (double depth : {0.5e-3, 1e-3, 2e-3, 3e-3}) {
    const double h = 0.02 * depth;
    double E[4];
    const double off[4] = {-2.0, -1.0, 1.0, 2.0};
    for (int i = 0; i < 4; ++i) E[i] = sphere_indentation_solution(d, depth + off[i] * h).energy_change;
    const double dEdd = (E[0] - 8.0 * E[1] + 8.0 * E[2] - E[3]) / (12.0 * h);
    EXPECT_NEAR(dEdd / sphere_indentation(d, depth).force, 1.0, 1e-6) << depth;
  }
}

// Consistency (not independent: an identity of the two contact balances): the contact pressure
// (T_s + T_t) / rho integrated over the wrapped cap equals the vertical pull of the membrane at
// its edge. Validity of the solution: the contact pressure stays compressive and the tensions
// positive (no wrinkling).
TEST(MembraneReference, WrappedCapIsInEquilibriumWithPositivePressure) {
  const MembraneDrum d;
  for (double depth : {0.05e-3, 1e-3, 3e-3, 6e-3}) {
    const IndentSolution s = sphere_indentation_solution(d, depth);
    EXPECT_NEAR(s.pressure_force / s.force, 1.0, 1e-9) << depth;
    EXPECT_GT(s.min_pressure, 0.0) << depth;
    EXPECT_GT(s.min_tension, 0.0) << depth;
    EXPECT_NEAR(s.contact_radius, d.sphere_radius * std::sin(s.contact_angle), 1e-15);
  }
}

// Dimensional analysis: F / Et is a function of lengths; scaling all lengths by k scales F and
// the contact radius by k, and F is proportional to Et.
TEST(MembraneReference, ScalesWithLengthAndStiffness) {
  const MembraneDrum d;
  const auto r = sphere_indentation(d, 2e-3);
  MembraneDrum big = d;
  big.rim_radius *= 3.0;
  big.sphere_radius *= 3.0;
  big.Et *= 0.5;
  const auto rb = sphere_indentation(big, 6e-3);
  EXPECT_NEAR(rb.force / (1.5 * r.force), 1.0, 1e-8);
  EXPECT_NEAR(rb.contact_radius / (3.0 * r.contact_radius), 1.0, 1e-8);
}

TEST(MembraneReference, RejectsBadInput) {
  const MembraneDrum d;
  EXPECT_THROW(sphere_indentation(d, -1e-3), std::invalid_argument);
  MembraneDrum slack = d;
  slack.prestretch = 1.0;
  EXPECT_THROW(sphere_indentation(slack, 1e-3), std::invalid_argument);
}
