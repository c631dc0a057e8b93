// The strain of a drawn cloth (clients/render/strain): a uniform stretch gives that weft strain.
#include <gtest/gtest.h>

#include "render_fixtures.hpp"

namespace {

using namespace hapticloth::render;
using namespace hapticloth::render::test;

TEST(Strain, UniformStretchGivesThatWeftStrain) {
  const Scene s = flat();
  ClothFrame f = rest_frame(s);
  for (auto& p : f.positions) p.x() *= 1.03f;
  std::vector<hapticloth::cloth::Strains> eps;
  StrainField(s).compute(f.positions, eps);
  ASSERT_EQ(eps.size(), s.triangles.size());
  for (const auto& e : eps) {
    EXPECT_NEAR(e.uu, 0.03, 1e-6);
    EXPECT_NEAR(e.vv, 0.0, 1e-6);
    EXPECT_NEAR(e.uv, 0.0, 1e-6);
  }
}


}  // namespace
