#include "cloth/element_partition.hpp"

#include <algorithm>
#include <stdexcept>

namespace hapticloth::cloth {

namespace {

// Labels vertices[lo, hi) with parts [first, first + count): median cut along the subset's
// longest side, then each half in turn.
void bisect(const std::vector<Vec3>& x, std::vector<int>& vertices, int lo, int hi, int first,
            int count, std::vector<int>& label) {
  if (count == 1 || hi - lo < 2) {
    for (int i = lo; i < hi; ++i) label[vertices[i]] = first;
    return;
  }
  Vec3 a = Vec3::Constant(1e300), b = Vec3::Constant(-1e300);
  for (int i = lo; i < hi; ++i) {
    a = a.cwiseMin(x[vertices[i]]);
    b = b.cwiseMax(x[vertices[i]]);
  }
  int axis;
  (b - a).maxCoeff(&axis);
  const int mid = lo + (hi - lo) / 2;
  std::nth_element(vertices.begin() + lo, vertices.begin() + mid, vertices.begin() + hi,
                   [&](int p, int q) { return x[p][axis] < x[q][axis] || (x[p][axis] == x[q][axis] && p < q); });
  bisect(x, vertices, lo, mid, first, count / 2, label);
  bisect(x, vertices, mid, hi, first + count / 2, count / 2, label);
}

}  // namespace

ElementPartition partition_elements(const std::vector<ElementRest>& elements,
                                    const std::vector<Vec3>& rest_positions, int parts) {
  if (parts < 1 || (parts & (parts - 1)) != 0)
    throw std::invalid_argument("partition_elements: parts must be a power of two");
  const int nv = static_cast<int>(rest_positions.size());
  std::vector<int> vertices(nv), label(nv, 0);
  for (int i = 0; i < nv; ++i) vertices[i] = i;
  bisect(rest_positions, vertices, 0, nv, 0, parts, label);
  ElementPartition p;
  p.parts.resize(parts);
  for (int t = 0; t < static_cast<int>(elements.size()); ++t) {
    const auto& v = elements[t].v;
    const int l = label[v[0]];
    if (label[v[1]] == l && label[v[2]] == l)
      p.parts[l].push_back(t);
    else
      p.separators.push_back(t);
  }
  return p;
}

}  // namespace hapticloth::cloth
