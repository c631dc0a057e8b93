#include "haptics/refinement/refined_regions.hpp"

#include "haptics/refinement/local_refinement.hpp"

namespace hapticloth::haptics {

void RefinedRegions::gather(const LocalRefinement& r, int fingers, std::uint64_t update) {
  version = update;
  x.clear();
  triangles.clear();
  weave_uv.clear();
  region.clear();
  for (int f = 0; f < fingers; ++f) {
    const RefinedContact* child = r.child(f);
    if (!child) continue;
    const int first = static_cast<int>(x.size());
    x.insert(x.end(), child->positions().begin(), child->positions().end());
    const cloth::Mesh& m = child->mesh().mesh;
    for (const auto& t : m.triangles) triangles.push_back({first + t[0], first + t[1], first + t[2]});
    weave_uv.insert(weave_uv.end(), m.weave_uv.begin(), m.weave_uv.end());
    region.insert(region.end(), child->mesh().region.begin(), child->mesh().region.end());
  }
}

}  // namespace hapticloth::haptics
