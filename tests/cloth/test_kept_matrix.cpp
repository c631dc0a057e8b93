// The kept matrix's bookkeeping (cloth/kept_matrix): which lanes' factors count as moved and
// what they leave to be added, when a matrix may be kept, and the changed rows' list. The
// integrator's tests hold the kept matrix against the one formed whole (test_integrator).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "cloth/kept_matrix.hpp"

using namespace hapticloth;
using cloth::JacobianMode;
using cloth::kFactors;
using cloth::kLanes;

namespace {

// Factors whose largest entry is 10 in every lane (entry 3), the others lane-dependent.
cloth::ElementTerms terms_with(double bump_lane0, double bump_lane1) {
  cloth::ElementTerms t{};
  for (int i = 0; i < kFactors; ++i)
    for (int l = 0; l < kLanes; ++l) t.factor[i][l] = i == 3 ? 10.0 : 0.1 * i + 0.01 * l;
  t.factor[5][0] += bump_lane0;
  t.factor[7][1] += bump_lane1;
  return t;
}

}  // namespace

// Against a tolerance of 1e-3 of the largest entry (10): a change of 0.02 moves, 0.005 does not.
// The moved lane takes the new factors and leaves their difference to be added; the others keep
// theirs and leave zero. Lanes past the group's count are never reported.
TEST(KeptMatrix, OnlyLanesThatMovedPastTheToleranceLeaveTheirDifference) {
  cloth::KeptMatrix kept(1e-3, {1}, 4);
  kept.keep_factors(0, 0, terms_with(0.0, 0.0));
  cloth::ElementTerms t = terms_with(0.02, 0.005);
  EXPECT_EQ(kept.take_changes(0, 0, kLanes, t), 1u);
  for (int i = 0; i < kFactors; ++i)
    for (int l = 0; l < kLanes; ++l) EXPECT_NEAR(t.factor[i][l], l == 0 && i == 5 ? 0.02 : 0.0, 1e-15) << i << " " << l;
  // Lane 0 now holds the new factors: the same again is no change; lane 1 still has the old
  // ones, so a further 0.006 (0.011 in all) moves it.
  t = terms_with(0.02, 0.011);
  EXPECT_EQ(kept.take_changes(0, 0, kLanes, t), 2u);
  EXPECT_NEAR(t.factor[7][1], 0.011, 1e-15);
  // Only the group's first `count` lanes are real.
  t = terms_with(0.02, 0.5);
  EXPECT_EQ(kept.take_changes(0, 0, 1, t), 0u);
}

// A factor that is not finite counts as moved, so that it reaches the solve and fails the step.
TEST(KeptMatrix, ANonFiniteFactorMoves) {
  cloth::KeptMatrix kept(1e-3, {1}, 4);
  kept.keep_factors(0, 0, terms_with(0.0, 0.0));
  cloth::ElementTerms t = terms_with(std::nan(""), 0.0);
  EXPECT_EQ(kept.take_changes(0, 0, kLanes, t), 1u);
  kept.keep_factors(0, 0, terms_with(0.0, 0.0));
  t = terms_with(0.0, HUGE_VAL);
  EXPECT_EQ(kept.take_changes(0, 0, kLanes, t), 2u);
}

// A matrix is kept only for the step, alpha and Jacobian mode it was formed for, while valid,
// and is formed whole again after kFullEvery kept assemblies; a tolerance of 0 never keeps.
TEST(KeptMatrix, KeepsOnlyTheSameStepAndModeForABoundedRun) {
  cloth::KeptMatrix kept(1e-4, {1}, 4);
  EXPECT_FALSE(kept.keeps(1e-3, 1.0, JacobianMode::Spd));  // nothing formed yet
  kept.assembled(1e-3, 1.0, JacobianMode::Spd, true);
  EXPECT_TRUE(kept.keeps(1e-3, 1.0, JacobianMode::Spd));
  EXPECT_FALSE(kept.keeps(0.5e-3, 1.0, JacobianMode::Spd));
  EXPECT_FALSE(kept.keeps(1e-3, 0.5, JacobianMode::Spd));
  EXPECT_FALSE(kept.keeps(1e-3, 1.0, JacobianMode::Exact));
  for (int k = 0; k < cloth::KeptMatrix::kFullEvery - 1; ++k) kept.assembled(1e-3, 1.0, JacobianMode::Spd, false);
  EXPECT_TRUE(kept.keeps(1e-3, 1.0, JacobianMode::Spd));
  kept.assembled(1e-3, 1.0, JacobianMode::Spd, false);
  EXPECT_FALSE(kept.keeps(1e-3, 1.0, JacobianMode::Spd));
  kept.assembled(1e-3, 1.0, JacobianMode::Spd, true);
  kept.invalidate();
  EXPECT_FALSE(kept.keeps(1e-3, 1.0, JacobianMode::Spd));
  cloth::KeptMatrix off(0.0, {1}, 4);
  off.assembled(1e-3, 1.0, JacobianMode::Spd, true);
  EXPECT_FALSE(off.keeps(1e-3, 1.0, JacobianMode::Spd));
}

// Rows marked by two parts come out once each, and the marks are cleared by taking them.
TEST(KeptMatrix, ChangedRowsComeOutOnceAndAreCleared) {
  cloth::KeptMatrix kept(1e-4, {1, 1}, 6);
  kept.mark(0, 4);
  kept.mark(0, 1);
  kept.mark(1, 4);
  kept.mark(1, 2);
  kept.mark(0, 1);
  std::vector<int> rows = kept.take_changed_rows();
  std::sort(rows.begin(), rows.end());
  EXPECT_EQ(rows, (std::vector<int>{1, 2, 4}));
  EXPECT_TRUE(kept.take_changed_rows().empty());
  kept.mark(1, 4);
  EXPECT_EQ(kept.take_changed_rows(), std::vector<int>{4});
}
