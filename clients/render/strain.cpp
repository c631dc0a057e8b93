#include "render/strain.hpp"

#include <limits>
#include <stdexcept>

namespace hapticloth::render {

double component(const cloth::Strains& s, StrainComponent c) {
  switch (c) {
    case StrainComponent::Weft: return s.uu;
    case StrainComponent::Warp: return s.vv;
    case StrainComponent::Shear: return s.uv;
  }
  return 0.0;
}

StrainField::StrainField(const Scene& scene) {
  const std::size_t n = scene.triangles.size();
  rest_.resize(n);
  degenerate_.assign(n, false);
  for (std::size_t i = 0; i < n; ++i) {
    const auto& t = scene.triangles[i];
    double uv[3][2];
    for (int k = 0; k < 3; ++k)
      for (int j = 0; j < 2; ++j) uv[k][j] = scene.weave_uv[i][k][j];
    try {
      rest_[i] = cloth::make_element(t[0], t[1], t[2], uv);
    } catch (const std::invalid_argument&) {
      degenerate_[i] = true;
    }
  }
}

void StrainField::compute(const std::vector<Vec3f>& x, std::vector<cloth::Strains>& out) const {
  constexpr double nan = std::numeric_limits<double>::quiet_NaN();
  out.resize(rest_.size());
  for (std::size_t i = 0; i < rest_.size(); ++i) {
    if (degenerate_[i]) {
      out[i] = {nan, nan, nan};
      continue;
    }
    const cloth::ElementRest& e = rest_[i];
    out[i] = cloth::element_strains(e, x[e.v[0]].cast<double>(), x[e.v[1]].cast<double>(),
                                    x[e.v[2]].cast<double>());
  }
}

}  // namespace hapticloth::render
