// Per-triangle in-plane strains of a cloth state (eq. 4), from the rest weave coordinates and
// the current positions, with the server's own element code.
#pragma once

#include <vector>

#include "cloth/element.hpp"
#include "render/recording.hpp"

namespace hapticloth::render {

enum class StrainComponent { Weft, Warp, Shear };

/// eps_uu (weft), eps_vv (warp) or eps_uv (shear) of eq. 4.
double component(const cloth::Strains& s, StrainComponent c);

class StrainField {
 public:
  /// Eq. 2 coefficients of every triangle from the scene's weave coordinates. A triangle that
  /// is degenerate in weave space gets NaN strains (drawn grey).
  explicit StrainField(const Scene& scene);

  /// Eq. 3-4 strains of every triangle at positions `x` (one per scene vertex).
  void compute(const std::vector<Vec3f>& x, std::vector<cloth::Strains>& out) const;

 private:
  std::vector<cloth::ElementRest> rest_;
  std::vector<bool> degenerate_;
};

}  // namespace hapticloth::render
