// The mesh budgets (server/app/mesh_budget.cpp): how large a cloth this machine holds, and how
// large a one the haptic loop can feel; each refusal names its figures.
#include <gtest/gtest.h>

#include <cmath>

#include "app/mesh_budget.hpp"

using namespace hapticloth::app;

TEST(MeshBudget, ThePcgStepFollowsItsPowerLawThroughTheReference) {
  EXPECT_NEAR(pcg_step_ms(static_cast<long>(kPcgRefTriangles)), kPcgRefStepMs, 1e-9);
  // Twice the mesh, 2^1.35 = 2.55x the step.
  EXPECT_NEAR(pcg_step_ms(2 * static_cast<long>(kPcgRefTriangles)) / kPcgRefStepMs, std::pow(2.0, kPcgExponent),
              1e-9);
  EXPECT_LT(pcg_step_ms(968), pcg_step_ms(4050));
}

TEST(MeshBudget, TheHapticLimitIsTheLargestMeshWhoseStepFits) {
  const long most = max_triangles_for_haptics();
  EXPECT_GT(most, 15842);  // the shipped 16k scene is felt
  EXPECT_LE(pcg_step_ms(most), kLongestGlobalStepMs + 1e-9);
  EXPECT_GT(pcg_step_ms(most + 1000), kLongestGlobalStepMs);
  EXPECT_EQ(haptic_budget_error(most), "");
  const std::string e = haptic_budget_error(4 * most);
  EXPECT_NE(e, "");
  EXPECT_NE(e.find(std::to_string(4 * most)), std::string::npos) << e;  // names the mesh's size
}

TEST(MeshBudget, TheMemoryLimitIsHalfThisMachinesMemory) {
  ASSERT_GT(physical_memory(), 0u);
  const long most = max_triangles_for_memory();
  EXPECT_NEAR(most * kBytesPerTriangle, 0.5 * static_cast<double>(physical_memory()), kBytesPerTriangle);
  EXPECT_EQ(memory_limit_error(most), "");
  const std::string e = memory_limit_error(most + 1000);
  EXPECT_NE(e, "");
  EXPECT_NE(e.find(std::to_string(most + 1000)), std::string::npos) << e;
}
