// The kept matrix's bookkeeping (cloth/kept_matrix): when a matrix may be kept, and the changed
// rows' list. Which elements' factors count as moved is the element pass's, tested at every
// instruction level in test_element_pass; the integrator's tests hold the kept matrix against
// the one formed whole (test_integrator).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "cloth/kept_matrix.hpp"

using namespace hapticloth;
using cloth::JacobianMode;

// A matrix is kept only for the step, alpha and Jacobian mode it was formed for, while valid,
// and is formed whole again after kFullEvery kept assemblies; a tolerance of 0 never keeps.
TEST(KeptMatrix, KeepsOnlyTheSameStepAndModeForABoundedRun) {
  cloth::KeptMatrix kept(1e-4, 1, 4);
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
  cloth::KeptMatrix off(0.0, 1, 4);
  off.assembled(1e-3, 1.0, JacobianMode::Spd, true);
  EXPECT_FALSE(off.keeps(1e-3, 1.0, JacobianMode::Spd));
}

// Rows marked by two parts come out once each, and the marks are cleared by taking them.
TEST(KeptMatrix, ChangedRowsComeOutOnceAndAreCleared) {
  cloth::KeptMatrix kept(1e-4, 2, 6);
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
