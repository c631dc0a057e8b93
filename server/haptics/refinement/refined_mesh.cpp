#include "haptics/refinement/refined_mesh.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace hapticloth::haptics {

namespace {
// A refinement this large means the spec does not fit the mesh (a finest edge far below the
// global one over a wide reach); the haptic budget could not solve it anyway.
constexpr std::size_t kMaxChildTriangles = 20000;

std::uint64_t edge_key(int a, int b) {
  if (a > b) std::swap(a, b);
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(a)) << 32) |
         static_cast<std::uint32_t>(b);
}

using Bary = std::array<double, 3>;

// Weave coordinates of a global triangle's corners, corner a at the origin, recovered from eq. 2:
// [ru_b rv_b; ru_c rv_c] is the inverse of the corners' weave differences [du_b du_c; dv_b dv_c].
std::array<std::array<double, 2>, 3> weave_corners(const cloth::ElementRest& e) {
  const double det = e.ru[1] * e.rv[2] - e.rv[1] * e.ru[2];
  const double dub = e.rv[2] / det, duc = -e.rv[1] / det;
  const double dvb = -e.ru[2] / det, dvc = e.ru[1] / det;
  return {{{0.0, 0.0}, {dub, dvb}, {duc, dvc}}};
}

struct ChildTri {
  std::array<int, 3> v;
  int parent;
  std::array<Bary, 3> b;  // each corner in the parent
};

int add_child_vertex(RefinedMesh& out, const Vec3& rest, const ClothPoint& at) {
  out.mesh.positions.push_back(rest);
  out.at.push_back(at);
  return static_cast<int>(out.at.size()) - 1;
}

// The region's global triangles as the first children, their vertices the first child vertices.
std::vector<ChildTri> seed_children(const cloth::ClothModel& g, RefinedMesh& out) {
  std::unordered_map<int, int> child_of;
  std::vector<ChildTri> tris;
  for (int t : out.region) {
    ChildTri ct{{0, 0, 0}, t, {}};
    for (int k = 0; k < 3; ++k) {
      const int gv = g.triangles[t][k];
      Bary b{0.0, 0.0, 0.0};
      b[k] = 1.0;
      auto it = child_of.find(gv);
      if (it == child_of.end()) it = child_of.emplace(gv, add_child_vertex(out, g.rest_positions[gv], {t, b})).first;
      ct.v[k] = it->second;
      ct.b[k] = b;
    }
    tris.push_back(ct);
  }
  return tris;
}

// Rivara's longest-edge bisection toward the contact point `c`: a child is split across its
// longest edge while that edge is longer than max(finest, grading x its distance from c), or
// while a neighbour's split left a midpoint on one of its edges (no hanging vertices).
void bisect_toward(const Vec3& c, const RefineSpec& spec, std::vector<ChildTri>& tris, RefinedMesh& out) {
  std::unordered_map<std::uint64_t, int> midpoint;
  const auto& P = out.mesh.positions;
  auto longest = [&](const ChildTri& t) {
    int k = 0;
    double best = -1.0;
    for (int e = 0; e < 3; ++e) {
      const double l = (P[t.v[e]] - P[t.v[(e + 1) % 3]]).squaredNorm();
      if (l > best) best = l, k = e;
    }
    return std::make_pair(k, std::sqrt(best));
  };
  auto too_big = [&](const ChildTri& t) {
    const double l = longest(t).second;
    const Vec3 centroid = (P[t.v[0]] + P[t.v[1]] + P[t.v[2]]) / 3.0;
    const double dist = std::max(0.0, (centroid - c).norm() - 0.5 * l);
    return l > std::max(spec.finest, spec.grading * dist) * (1.0 + 1e-9);
  };
  auto hanging = [&](const ChildTri& t) {
    for (int e = 0; e < 3; ++e)
      if (midpoint.count(edge_key(t.v[e], t.v[(e + 1) % 3]))) return true;
    return false;
  };
  // The midpoint of edge (a, b) of t, made once and shared by the triangles on either side.
  auto midpoint_of = [&](const ChildTri& t, int a, int b, const Bary& mb) {
    const auto it = midpoint.find(edge_key(a, b));
    if (it != midpoint.end()) return it->second;
    const int m = add_child_vertex(out, 0.5 * (P[a] + P[b]), {t.parent, mb});
    midpoint.emplace(edge_key(a, b), m);
    return m;
  };
  for (bool changed = true; changed;) {
    changed = false;
    for (std::size_t i = 0; i < tris.size(); ++i) {
      while (too_big(tris[i]) || hanging(tris[i])) {
        if (tris.size() >= kMaxChildTriangles)
          throw std::runtime_error("refinement: more than " + std::to_string(kMaxChildTriangles) +
                                   " child triangles; the finest edge is too small for the mesh");
        const ChildTri t = tris[i];
        const int k = longest(t).first;  // edge (k, k+1), opposite corner k+2
        Bary mb;
        for (int j = 0; j < 3; ++j) mb[j] = 0.5 * (t.b[k][j] + t.b[(k + 1) % 3][j]);
        const int m = midpoint_of(t, t.v[k], t.v[(k + 1) % 3], mb);
        ChildTri t1 = t, t2 = t;  // (a, m, o) and (m, b, o), the parent's orientation
        t1.v[(k + 1) % 3] = m;
        t1.b[(k + 1) % 3] = mb;
        t2.v[k] = m;
        t2.b[k] = mb;
        tris[i] = t1;
        tris.push_back(t2);
        changed = true;
      }
    }
  }
}

// The children as the refined mesh's triangles, with weave coordinates interpolated in each
// child's global triangle, and the finest edge.
void add_triangles(const cloth::ClothModel& g, const std::vector<ChildTri>& tris, RefinedMesh& out) {
  const auto& P = out.mesh.positions;
  out.finest_edge = 1e300;
  for (const ChildTri& t : tris) {
    const auto uv = weave_corners(g.elements[t.parent]);
    std::array<std::array<double, 2>, 3> cuv{};
    for (int k = 0; k < 3; ++k)
      for (int d = 0; d < 2; ++d)
        cuv[k][d] = t.b[k][0] * uv[0][d] + t.b[k][1] * uv[1][d] + t.b[k][2] * uv[2][d];
    out.mesh.triangles.push_back(t.v);
    out.mesh.weave_uv.push_back(cuv);
    for (int e = 0; e < 3; ++e)
      out.finest_edge = std::min(out.finest_edge, (P[t.v[e]] - P[t.v[(e + 1) % 3]]).norm());
  }
}
}  // namespace

void RefinedMesh::place(const std::vector<Vec3>& global_x, std::vector<Vec3>& x) const {
  x.resize(at.size());
  for (std::size_t i = 0; i < at.size(); ++i) x[i] = at[i].b[0] * global_x[tri_vertices[i][0]] +
                                                  at[i].b[1] * global_x[tri_vertices[i][1]] +
                                                  at[i].b[2] * global_x[tri_vertices[i][2]];
}

MeshRefiner::MeshRefiner(const cloth::ClothModel& global) : g_(global) {
  vertex_tris_.resize(g_.num_vertices());
  for (int t = 0; t < static_cast<int>(g_.triangles.size()); ++t) {
    const auto& v = g_.triangles[t];
    for (int k = 0; k < 3; ++k) {
      ++edge_uses_[edge_key(v[k], v[(k + 1) % 3])];
      vertex_tris_[v[k]].push_back(t);
    }
  }
}

double MeshRefiner::longest_edge(int t) const {
  const auto& v = g_.triangles[t];
  double e = 0.0;
  for (int k = 0; k < 3; ++k)
    e = std::max(e, (g_.rest_positions[v[k]] - g_.rest_positions[v[(k + 1) % 3]]).norm());
  return e;
}

Vec3 MeshRefiner::rest_point(const ClothPoint& p) const {
  const auto& v = g_.triangles[p.tri];
  return p.b[0] * g_.rest_positions[v[0]] + p.b[1] * g_.rest_positions[v[1]] +
         p.b[2] * g_.rest_positions[v[2]];
}

// The global triangles with a corner within `reach` of the contact (rest), grown from the
// contact's triangle across shared vertices: the cost follows the region, not the mesh.
std::vector<int> MeshRefiner::region_around(const ClothPoint& contact, double reach) const {
  const Vec3 c = rest_point(contact);
  std::vector<int> region{contact.tri}, frontier{contact.tri};
  std::vector<int> seen_v;
  auto near = [&](int v) { return (g_.rest_positions[v] - c).norm() <= reach; };
  while (!frontier.empty()) {
    const int t = frontier.back();
    frontier.pop_back();
    for (int v : g_.triangles[t]) {
      if (!near(v) || std::find(seen_v.begin(), seen_v.end(), v) != seen_v.end()) continue;
      seen_v.push_back(v);
      for (int u : vertex_tris_[v])
        if (std::find(region.begin(), region.end(), u) == region.end()) {
          region.push_back(u);
          frontier.push_back(u);
        }
    }
  }
  std::sort(region.begin(), region.end());
  return region;
}

RefinedMesh MeshRefiner::refine(const ClothPoint& contact, const RefineSpec& spec) const {
  if (!(spec.finest > 0.0) || !(spec.grading > 0.0) || !(spec.reach > 0.0))
    throw std::invalid_argument("refinement: finest edge, grading and reach must be positive");
  RefinedMesh out;
  out.region = region_around(contact, spec.reach);
  std::vector<ChildTri> tris = seed_children(g_, out);
  bisect_toward(rest_point(contact), spec, tris, out);
  out.held = held_children(out);
  for (const ClothPoint& p : out.at) out.tri_vertices.push_back(g_.triangles[p.tri]);
  add_triangles(g_, tris, out);
  return out;
}

// Which child vertices follow the global cloth: those on an edge or a vertex the region shares
// with the rest of the cloth, and the cloth's pins. (Barycentric zeros are exact: midpoints of
// exact zeros.)
std::vector<int> MeshRefiner::held_children(const RefinedMesh& out) const {
  std::vector<char> in_region(g_.triangles.size(), 0);
  for (int t : out.region) in_region[t] = 1;
  auto vertex_on_interface = [&](int gv) {
    for (int u : vertex_tris_[gv])
      if (!in_region[u]) return true;
    return false;
  };
  auto edge_on_interface = [&](int ga, int gb) {
    // Used twice in the cloth and once in the region: the other triangle is outside.
    const auto it = edge_uses_.find(edge_key(ga, gb));
    if (it == edge_uses_.end() || it->second < 2) return false;  // the cloth's free edge
    int inside = 0;
    for (int u : vertex_tris_[ga])
      if (in_region[u]) {
        const auto& v = g_.triangles[u];
        if (std::find(v.begin(), v.end(), gb) != v.end()) ++inside;
      }
    return inside < 2;
  };
  std::vector<int> held;
  for (int i = 0; i < static_cast<int>(out.at.size()); ++i) {
    const ClothPoint& p = out.at[i];
    const auto& gv = g_.triangles[p.tri];
    int zeros = 0, corner = -1, missing = -1;
    for (int k = 0; k < 3; ++k) {
      if (p.b[k] == 0.0) ++zeros, missing = k;
      if (p.b[k] == 1.0) corner = k;
    }
    bool on_interface = false;
    if (corner >= 0) on_interface = g_.pinned[gv[corner]] || vertex_on_interface(gv[corner]);
    else if (zeros == 1) on_interface = edge_on_interface(gv[(missing + 1) % 3], gv[(missing + 2) % 3]);
    if (on_interface) held.push_back(i);
  }
  return held;
}

}  // namespace hapticloth::haptics
