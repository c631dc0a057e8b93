#include "cloth/element_partition.hpp"

#include <algorithm>
#include <numeric>
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

// The elements whose corners have different labels.
int crossing(const std::vector<ElementRest>& elements, const std::vector<int>& label) {
  int n = 0;
  for (const auto& e : elements) n += label[e.v[0]] != label[e.v[1]] || label[e.v[0]] != label[e.v[2]];
  return n;
}

}  // namespace

ElementPartition partition_elements(const std::vector<ElementRest>& elements,
                                    const std::vector<Vec3>& rest_positions, int parts) {
  if (parts < 1 || (parts & (parts - 1)) != 0)
    throw std::invalid_argument("partition_elements: parts must be a power of two");
  const int nv = static_cast<int>(rest_positions.size());
  std::vector<int> vertices(nv), label(nv, 0);
  // The first cut halves the vertices by number, the rest by position (bisect). The caller's
  // half (parts [0, parts/2), which the assembly's caller claims first) is then the mesh's
  // first half, as the PCG's first part is (pcg_ordering.cpp: sweep_order), so the rows a thread
  // assembles are the rows it sweeps and stay in its core's cache. A mesh numbered so that the
  // cut by number crosses far more elements than one by position is cut by position throughout.
  std::vector<int> by_number(nv, 0);
  for (int i = nv / 2; i < nv; ++i) by_number[i] = 1;
  std::iota(vertices.begin(), vertices.end(), 0);
  bisect(rest_positions, vertices, 0, nv, 0, 2, label);  // the first cut by position, to compare
  const bool number_first = parts > 1 && crossing(elements, by_number) <= 2 * crossing(elements, label);
  std::iota(vertices.begin(), vertices.end(), 0);
  if (number_first) {
    bisect(rest_positions, vertices, 0, nv / 2, 0, parts / 2, label);
    bisect(rest_positions, vertices, nv / 2, nv, parts / 2, parts / 2, label);
  } else {
    bisect(rest_positions, vertices, 0, nv, 0, parts, label);
  }
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
