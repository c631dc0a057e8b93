#include "cloth/mesh.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <utility>

#include <Eigen/Geometry>
#include <stdexcept>

namespace hapticloth::cloth {

Mesh make_grid(const GridSpec& s) {
  if (s.nx < 1 || s.ny < 1) throw std::invalid_argument("grid resolution must be at least 1 x 1");
  if (!(s.width > 0.0) || !(s.height > 0.0)) throw std::invalid_argument("grid size must be > 0");
  Mesh m;
  m.grid_nx = s.nx;
  m.grid_ny = s.ny;
  Eigen::Vector3d ax(1, 0, 0), ay(0, 1, 0);
  switch (s.plane) {
    case GridPlane::XY: ax = {1, 0, 0}; ay = {0, 1, 0}; break;
    case GridPlane::XZ: ax = {1, 0, 0}; ay = {0, 0, 1}; break;
    case GridPlane::YZ: ax = {0, 1, 0}; ay = {0, 0, 1}; break;
  }
  const double th = s.weave_angle_deg * M_PI / 180.0, c = std::cos(th), sn = std::sin(th);
  std::vector<std::array<double, 2>> uv;
  for (int j = 0; j <= s.ny; ++j) {
    for (int i = 0; i <= s.nx; ++i) {
      const double a = s.width * i / s.nx, b = s.height * j / s.ny;
      m.positions.push_back(s.origin + a * ax + b * ay);
      // weft axis at angle th from the grid's first axis
      uv.push_back({c * a + sn * b, -sn * a + c * b});
    }
  }
  auto id = [&](int i, int j) { return j * (s.nx + 1) + i; };
  auto add = [&](int a, int b, int cc) {
    m.triangles.push_back({a, b, cc});
    m.weave_uv.push_back({uv[a], uv[b], uv[cc]});
  };
  for (int j = 0; j < s.ny; ++j) {
    for (int i = 0; i < s.nx; ++i) {
      const int p00 = id(i, j), p10 = id(i + 1, j), p01 = id(i, j + 1), p11 = id(i + 1, j + 1);
      if (!s.alternate_diagonals || (i + j) % 2 == 0) {
        add(p00, p10, p11);
        add(p00, p11, p01);
      } else {
        add(p00, p10, p01);
        add(p10, p11, p01);
      }
    }
  }
  return m;
}

std::array<std::array<double, 2>, 3> flatten_triangle(const Eigen::Vector3d p[3],
                                                      const Eigen::Vector3d& weft_dir3d) {
  const Eigen::Vector3d e1 = p[1] - p[0], e2 = p[2] - p[0];
  Eigen::Vector3d n = e1.cross(e2);
  const double nn = n.norm();
  if (!(nn > 0.0)) throw std::invalid_argument("degenerate triangle in the rest shape");
  n /= nn;
  Eigen::Vector3d u = weft_dir3d - weft_dir3d.dot(n) * n;  // weft direction in the plane
  if (!(u.norm() > 1e-12)) u = e1;
  u.normalize();
  const Eigen::Vector3d v = n.cross(u);
  std::array<std::array<double, 2>, 3> out;
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d d = p[k] - p[0];
    out[k] = {d.dot(u), d.dot(v)};
  }
  return out;
}

std::vector<int> grid_edge(const Mesh& m, const std::string& edge) {
  if (m.grid_nx <= 0) throw std::invalid_argument("named edges exist only on generated grids");
  std::vector<int> out;
  const int nx = m.grid_nx, ny = m.grid_ny;
  if (edge == "bottom" || edge == "top") {
    const int j = edge == "bottom" ? 0 : ny;
    for (int i = 0; i <= nx; ++i) out.push_back(j * (nx + 1) + i);
  } else if (edge == "left" || edge == "right") {
    const int i = edge == "left" ? 0 : nx;
    for (int j = 0; j <= ny; ++j) out.push_back(j * (nx + 1) + i);
  } else {
    throw std::invalid_argument("unknown edge '" + edge + "' (top, bottom, left, right)");
  }
  return out;
}

namespace {

void require(bool ok, const std::string& field, const std::string& what) {
  if (!ok) throw std::invalid_argument("DiscSpec." + field + " " + what);
}

double signed_area_xy(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  return 0.5 * ((b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x()));
}

void check_disc_spec(const DiscSpec& s) {
  const auto finite_positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  require(finite_positive(s.radius), "radius", "must be positive and finite");
  require(finite_positive(s.centre_edge), "centre_edge", "must be positive and finite");
  require(finite_positive(s.rim_edge), "rim_edge", "must be positive and finite");
  require(std::isfinite(s.growth) && s.growth >= 1.0, "growth", "must be finite and >= 1");
  require(s.centre.allFinite(), "centre", "must be finite");
  require(s.centre_edge <= s.rim_edge, "centre_edge", "must be <= rim_edge");
  require(s.rim_edge < s.radius, "rim_edge", "must be < radius");
}

// The rings of a disc: ring 0 is the centre vertex, ring k (1..K) holds count[k] vertices from
// index first[k], at radius r[k], turned by offset[k] of its angular spacing.
struct Rings {
  std::vector<double> r;
  std::vector<int> count, first;
  std::vector<double> offset;
  std::size_t rings() const { return r.size() - 1; }
};

// Ring radii: r_0 = 0 (centre vertex), r_{k+1} = r_k + h_k, h_k = min(centre_edge g^k,
// rim_edge); stop at the first ring beyond the radius, then end on it or on the ring
// before, whichever needs the smaller uniform rescaling to put the last ring at `radius`.
std::vector<double> ring_radii(const DiscSpec& s) {
  constexpr std::size_t kMaxRings = 100000;
  std::vector<double> r{0.0};
  double h = s.centre_edge;
  while (r.back() < s.radius) {
    r.push_back(r.back() + h);
    h = std::min(h * s.growth, s.rim_edge);
    require(r.size() <= kMaxRings, "centre_edge", "gives more than 100000 rings (too small)");
  }
  if (r.size() > 2 && std::log(r[r.size() - 1] / s.radius) > std::log(s.radius / r[r.size() - 2]))
    r.pop_back();
  const double scale = s.radius / r.back();
  for (double& x : r) x *= scale;
  r.back() = s.radius;
  return r;
}

// Vertex counts: ring 1 is a hexagon, ring k holds round(2 pi r_k / h_k) vertices with h_k
// the mean of the radial spacings on either side (the inner one on the last ring). Returns
// the total number of vertices.
double count_ring_vertices(Rings& g) {
  const std::size_t K = g.rings();
  const std::vector<double>& r = g.r;
  g.count.assign(K + 1, 1);
  double total = 1.0;
  for (std::size_t k = 1; k <= K; ++k) {
    const double hk = k < K ? 0.5 * (r[k + 1] - r[k - 1]) : r[k] - r[k - 1];
    const double n = k == 1 ? 6.0 : std::max(6.0, std::round(2.0 * M_PI * r[k] / hk));
    total += n;
    require(total < 2.0e7, "centre_edge", "gives more than 2e7 vertices (too small)");
    g.count[k] = static_cast<int>(n);
  }
  return total;
}

// The centre vertex, then each ring's vertices evenly spaced, neighbouring rings staggered.
void place_ring_vertices(const Eigen::Vector3d& centre, Rings& g, Mesh& m) {
  const std::size_t K = g.rings();
  g.first.assign(K + 1, 0);
  g.offset.assign(K + 1, 0.0);  // angular offset of each ring, in units of its spacing
  m.positions.push_back(centre);
  for (std::size_t k = 1; k <= K; ++k) {
    g.first[k] = static_cast<int>(m.positions.size());
    g.offset[k] = (k % 2 == 0) ? 0.5 : 0.0;  // stagger neighbouring rings
    for (int j = 0; j < g.count[k]; ++j) {
      const double th = 2.0 * M_PI * (j + g.offset[k]) / g.count[k];
      m.positions.push_back(centre + Eigen::Vector3d(g.r[k] * std::cos(th), g.r[k] * std::sin(th), 0.0));
    }
  }
}

// A triangle with weave_uv = its corners' rest (x, y) about the centre (weft along x).
void add_disc_triangle(Mesh& m, const Eigen::Vector3d& centre, int a, int b, int c) {
  m.triangles.push_back({a, b, c});
  std::array<std::array<double, 2>, 3> uv;
  const int v[3] = {a, b, c};
  for (int q = 0; q < 3; ++q)
    uv[q] = {m.positions[v[q]].x() - centre.x(), m.positions[v[q]].y() - centre.y()};
  m.weave_uv.push_back(uv);
}

// The strip between rings k (inner, A) and k + 1 (outer, B): advance along both rings, each
// time along the shorter diagonal, never emitting an inverted triangle when the other choice
// is valid.
void stitch_rings(const Eigen::Vector3d& centre, const Rings& g, std::size_t k, Mesh& m) {
  const int na = g.count[k], nb = g.count[k + 1];
  const auto A = [&](int i) { return g.first[k] + ((i % na) + na) % na; };
  // Start B at the vertex angularly nearest to A_0.
  const double tha = 2.0 * M_PI * g.offset[k] / na;
  int j0 = static_cast<int>(std::lround(tha / (2.0 * M_PI) * nb - g.offset[k + 1]));
  const auto B = [&](int j) { return g.first[k + 1] + (((j + j0) % nb) + nb) % nb; };
  int i = 0, j = 0;
  while (i < na || j < nb) {
    bool advance_a;
    if (i == na) {
      advance_a = false;
    } else if (j == nb) {
      advance_a = true;
    } else {
      const auto& P = m.positions;
      advance_a = (P[A(i + 1)] - P[B(j)]).squaredNorm() <= (P[A(i)] - P[B(j + 1)]).squaredNorm();
      const double area_a = signed_area_xy(P[A(i)], P[B(j)], P[A(i + 1)]);
      const double area_b = signed_area_xy(P[A(i)], P[B(j)], P[B(j + 1)]);
      if (advance_a && !(area_a > 0.0) && area_b > 0.0) advance_a = false;
      if (!advance_a && !(area_b > 0.0) && area_a > 0.0) advance_a = true;
    }
    if (advance_a) {
      add_disc_triangle(m, centre, A(i), B(j), A(i + 1));
      ++i;
    } else {
      add_disc_triangle(m, centre, A(i), B(j), B(j + 1));
      ++j;
    }
  }
}

}  // namespace

Mesh make_disc(const DiscSpec& s) {
  check_disc_spec(s);
  Rings g;
  g.r = ring_radii(s);
  const double total = count_ring_vertices(g);
  Mesh m;
  m.positions.reserve(static_cast<std::size_t>(total));
  place_ring_vertices(s.centre, g, m);
  // Centre fan.
  for (int j = 0; j < g.count[1]; ++j)
    add_disc_triangle(m, s.centre, 0, g.first[1] + j, g.first[1] + (j + 1) % g.count[1]);
  for (std::size_t k = 1; k < g.rings(); ++k) stitch_rings(s.centre, g, k, m);
  return m;
}

std::vector<int> disc_rim(const Mesh& mesh) {
  // Directed boundary edges: an edge (a, b) of a triangle whose reverse (b, a) is in no
  // triangle and which is not repeated.
  std::map<std::pair<int, int>, int> directed;
  for (const auto& t : mesh.triangles)
    for (int q = 0; q < 3; ++q) ++directed[{t[q], t[(q + 1) % 3]}];
  std::map<int, int> next;  // boundary successor of each boundary vertex
  for (const auto& [e, n] : directed)
    if (n == 1 && directed.find({e.second, e.first}) == directed.end()) next[e.first] = e.second;
  if (next.empty()) throw std::invalid_argument("disc_rim: the mesh has no boundary edges");
  std::vector<int> best;
  std::set<int> seen;
  for (const auto& [start, unused] : next) {
    (void)unused;
    if (seen.count(start)) continue;
    std::vector<int> loop;
    int v = start;
    while (!seen.count(v)) {
      seen.insert(v);
      loop.push_back(v);
      const auto it = next.find(v);
      if (it == next.end()) break;
      v = it->second;
    }
    if (loop.size() > best.size()) best = std::move(loop);
  }
  return best;
}

}  // namespace hapticloth::cloth
