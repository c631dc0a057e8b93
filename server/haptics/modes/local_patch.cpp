#include "haptics/modes/local_patch.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

namespace hapticloth::haptics {

LocalPatch::LocalPatch(const std::vector<std::array<int, 3>>& global_tris,
                       const std::vector<Vec3>& rest_positions, const std::vector<char>& pinned,
                       const PatchParams& p)
    : gt_(global_tris), rest_(rest_positions), pinned_(pinned), p_(p) {
  const int T = p_.max_triangles;
  const int V = 6 * T + 8, E = 12 * T + 8;
  edge_end_a_.assign(V, 0);
  edge_end_b_.assign(V, 0);
  border_.assign(V, 0);
  x_.assign(V, Vec3::Zero());
  v_.assign(V, Vec3::Zero());
  n_.assign(V, Vec3::UnitZ());
  f_.assign(V, Vec3::Zero());
  m_.assign(V, 0.0);
  tri_.assign(4 * T, {0, 0, 0});
  edge_.assign(E, {0, 0});
  rest_len_.assign(E, 0.0);
  k_.assign(E, 0.0);
  vertex_stiffness_.assign(V, 0.0);
  sel_.assign(T, 0);
  key_.assign(4 * V, {-1, -1, -1});
  edge_key_.assign(4 * E, {-1, -1, -1});
  uses_.assign(V, 0);
  kernel_vertex_.assign(128, 0);
  kernel_weight_.assign(128, 0.0);
  x0_.assign(128, Vec3::Zero());
}

void LocalPatch::rebuild(const ClothSnapshot& s, int finger, const Vec3& c) noexcept {
  nt_ = nv_ = ne_ = 0;
  centre_ = c;
  const int ns = select(s, finger, c);
  if (ns == 0) return;
  subdivide(ns);
  springs();
  mark_border(ns);
  for (int v = 0; v < nv_; ++v) {
    x_[v] = 0.5 * (s.x[edge_end_a_[v]] + s.x[edge_end_b_[v]]);
    v_[v] = 0.5 * (s.v[edge_end_a_[v]] + s.v[edge_end_b_[v]]);
  }
  stable_substeps();
  double el = 0.0;
  for (int e = 0; e < ne_; ++e) el += rest_len_[e];
  edge_mean_ = ne_ ? el / ne_ : 0.0;
  normals();
}

// Global triangles with a corner within the radius, in index order up to the capacity, among
// the finger's candidates that the simulation thread listed in the snapshot (never a scan of
// the whole mesh here, on the haptic thread).
int LocalPatch::select(const ClothSnapshot& s, int finger, const Vec3& c) noexcept {
  int ns = 0;
  const double R2 = p_.radius * p_.radius;
  const std::vector<int>& cand = s.near_triangles[finger];
  for (int i = 0; i < s.near_count[finger] && ns < p_.max_triangles; ++i) {
    const int t = cand[i];
    const auto& g = gt_[t];
    bool in = false;
    for (int k = 0; k < 3; ++k) in = in || (s.x[g[k]] - c).squaredNorm() < R2;
    if (in) sel_[ns++] = t;
  }
  return ns;
}

namespace {
// The value of unordered pair (a, b) in an open-addressing hash table of (a, b, value) entries
// (a < 0: empty), or, if it is not there, `next` stored for it (`added` says which). The
// tables hold 4x their capacity, so a free entry is always found.
int find_or_add(std::vector<std::array<int, 3>>& table, int a, int b, int next, bool& added) noexcept {
  if (a > b) std::swap(a, b);
  const int cap = static_cast<int>(table.size());
  const unsigned h = (static_cast<unsigned>(a) * 73856093u) ^ (static_cast<unsigned>(b) * 19349663u);
  added = false;
  for (int i = 0; i < cap; ++i) {
    auto& e = table[(h + i) % cap];
    if (e[0] == a && e[1] == b) return e[2];
    if (e[0] < 0) {
      e = {a, b, next};
      added = true;
      return next;
    }
  }
  return 0;  // unreachable
}
}  // namespace

// The patch vertex of global vertex a (a == b) or of the midpoint of global edge (a, b).
int LocalPatch::patch_vertex(int a, int b) noexcept {
  bool added;
  const int v = find_or_add(key_, a, b, nv_, added);
  if (added) {
    edge_end_a_[v] = std::min(a, b);
    edge_end_b_[v] = std::max(a, b);
    border_[v] = 0;
    uses_[v] = 0;
    m_[v] = 0.0;
    ++nv_;
  }
  return v;
}

// Each selected global triangle into four, at its edge midpoints. A midpoint's use count is
// the number of selected triangles on its global edge (mark_border).
void LocalPatch::subdivide(int ns) noexcept {
  for (auto& k : key_) k = {-1, -1, -1};
  for (int i = 0; i < ns; ++i) {
    const auto& g = gt_[sel_[i]];
    const int a = patch_vertex(g[0], g[0]), b = patch_vertex(g[1], g[1]), cc = patch_vertex(g[2], g[2]);
    const int ab = patch_vertex(g[0], g[1]), bc = patch_vertex(g[1], g[2]), ca = patch_vertex(g[2], g[0]);
    ++uses_[ab];
    ++uses_[bc];
    ++uses_[ca];
    tri_[nt_++] = {a, ab, ca};
    tri_[nt_++] = {ab, b, bc};
    tri_[nt_++] = {ca, bc, cc};
    tri_[nt_++] = {ab, bc, ca};
  }
}

// The refined edge (i, j), with its rest length when first met.
int LocalPatch::refined_edge(int i, int j) noexcept {
  bool added;
  const int e = find_or_add(edge_key_, i, j, ne_, added);
  if (added) {
    edge_[e] = {std::min(i, j), std::max(i, j)};
    rest_len_[e] = (0.5 * (rest_[edge_end_a_[i]] + rest_[edge_end_b_[i]]) - 0.5 * (rest_[edge_end_a_[j]] + rest_[edge_end_b_[j]])).norm();
    k_[e] = 0.0;
    ++ne_;
  }
  return e;
}

// Rest geometry, masses (area / 3 per corner) and springs along every refined edge, each edge
// once, with stiffness E x (adjacent area) / L^2 (a spring network of modulus E).
void LocalPatch::springs() noexcept {
  auto rest_of = [&](int v) { return 0.5 * (rest_[edge_end_a_[v]] + rest_[edge_end_b_[v]]); };
  ne_ = 0;
  for (auto& k : edge_key_) k = {-1, -1, -1};
  for (int t = 0; t < nt_; ++t) {
    const auto& tr = tri_[t];
    const Vec3 a = rest_of(tr[0]), b = rest_of(tr[1]), cc = rest_of(tr[2]);
    const double area = 0.5 * (b - a).cross(cc - a).norm();
    for (int k = 0; k < 3; ++k) {
      m_[tr[k]] += p_.areal_density * area / 3.0;
      const int e = refined_edge(tr[k], tr[(k + 1) % 3]);
      k_[e] += p_.stiffness * (area / 2.0) / (rest_len_[e] * rest_len_[e]);
    }
  }
}

// Border: refined vertices on the boundary of the patch (global edges used by one selected
// triangle: their midpoint's use count is 1) and pinned ones follow the global cloth.
void LocalPatch::mark_border(int ns) noexcept {
  for (int i = 0; i < ns; ++i) {
    const auto& g = gt_[sel_[i]];
    for (int k = 0; k < 3; ++k) {
      const int a = g[k], b = g[(k + 1) % 3];
      const int mid = patch_vertex(a, b);  // found: subdivide() made it
      if (uses_[mid] == 1) border_[patch_vertex(a, a)] = border_[patch_vertex(b, b)] = border_[mid] = 1;
    }
  }
  for (int v = 0; v < nv_; ++v)
    if (pinned_[edge_end_a_[v]] || pinned_[edge_end_b_[v]]) border_[v] = 1;
}

// Substeps for a stable explicit step: omega_max h < 2, with omega_max^2 bounded by Gershgorin
// as max over interior vertices of 2 (sum of spring stiffness) / m plus the fingertip spring on
// the lightest vertex. Taken so that omega_max h <= 1 (margin for the damping terms). Beyond
// max_substeps the springs are softened instead: a patch stiffer than the fingertip spring (the
// device's renderable stiffness) does not change what is felt.
void LocalPatch::stable_substeps() noexcept {
  for (int v = 0; v < nv_; ++v) vertex_stiffness_[v] = 0.0;
  for (int e = 0; e < ne_; ++e) {
    vertex_stiffness_[edge_[e][0]] += k_[e];
    vertex_stiffness_[edge_[e][1]] += k_[e];
  }
  double w2_springs = 0.0, m_min = 1e300;
  for (int v = 0; v < nv_; ++v) {
    if (border_[v] || m_[v] <= 0.0) continue;
    w2_springs = std::max(w2_springs, 2.0 * vertex_stiffness_[v] / m_[v]);
    m_min = std::min(m_min, m_[v]);
  }
  const double tick = p_.haptic_period;
  const double w2_contact = m_min < 1e300 ? p_.contact_stiffness / m_min : 0.0;
  const double needed = std::ceil(tick * std::sqrt(w2_springs + w2_contact));
  const int lo = std::max(1, p_.substeps), hi = std::max(lo, p_.max_substeps);
  spring_scale_ = 1.0;
  if (needed <= hi) {
    substeps_ = std::max(lo, static_cast<int>(needed));
  } else {
    substeps_ = hi;
    const double w2_allowed = (hi / tick) * (hi / tick);
    spring_scale_ = std::max(0.0, w2_allowed - w2_contact) / w2_springs;
    for (int e = 0; e < ne_; ++e) k_[e] *= spring_scale_;
  }
}

void LocalPatch::border_positions(const ClothSnapshot& s, double now) noexcept {
  const double dt = std::clamp(now - s.time, 0.0, 0.1);
  for (int v = 0; v < nv_; ++v) {
    if (!border_[v]) continue;
    const Vec3 vel = 0.5 * (s.v[edge_end_a_[v]] + s.v[edge_end_b_[v]]);
    x_[v] = 0.5 * (s.x[edge_end_a_[v]] + s.x[edge_end_b_[v]]) + dt * vel;  // constant velocity (4.2)
    v_[v] = vel;
  }
}

void LocalPatch::normals() noexcept {
  for (int v = 0; v < nv_; ++v) n_[v].setZero();
  for (int t = 0; t < nt_; ++t) {
    const auto& tr = tri_[t];
    const Vec3 n = (x_[tr[1]] - x_[tr[0]]).cross(x_[tr[2]] - x_[tr[0]]);
    for (int k = 0; k < 3; ++k) n_[tr[k]] += n;
  }
  for (int v = 0; v < nv_; ++v) {
    const double l = n_[v].norm();
    n_[v] = l > 0.0 ? Vec3(n_[v] / l) : Vec3::UnitZ();
  }
}

Vec3 LocalPatch::step(const ClothSnapshot& s, double now, const PatchTouch& touch, Vec3& anchor,
                      bool& slipping) noexcept {
  slipping = false;
  if (nt_ == 0) return Vec3::Zero();
  border_positions(s, now);
  const int n = substeps_;
  const double h = p_.haptic_period / n;
  const bool touching = touch.contact && touch.tri >= 0 && touch.tri < nt_;
  const Kernel K = touching ? contact_kernel(touch) : Kernel{};
  Vec3 q_prev = K.q0;
  Vec3 user = Vec3::Zero();
  for (int it = 0; it < n; ++it) {
    spring_forces();
    if (touching) user += contact_forces(touch, K, anchor, q_prev, slipping);
    integrate(s, h);
  }
  normals();
  return user / n;
}

// The touched point and its neighbourhood: the contact force is spread over the patch vertices
// within a fingertip's reach with a smooth kernel (as on the global cloth), and the touched
// point moves with their weighted displacement. A point force on the light refined vertices
// would dent and release them one by one as the finger slides.
LocalPatch::Kernel LocalPatch::contact_kernel(const PatchTouch& touch) noexcept {
  Kernel K;
  const double* b = touch.b;
  const auto& t = tri_[touch.tri];
  K.q0 = b[0] * x_[t[0]] + b[1] * x_[t[1]] + b[2] * x_[t[2]];
  K.n0 = (b[0] * n_[t[0]] + b[1] * n_[t[1]] + b[2] * n_[t[2]]).normalized() * touch.side;
  const double R = std::max(touch.r, 1.5 * edge_mean_), R2 = R * R;
  double sum = 0.0;
  int& nw = K.n;
  for (int v = 0; v < nv_ && nw < static_cast<int>(kernel_vertex_.size()); ++v) {
    const double d2 = (x_[v] - K.q0).squaredNorm();
    if (d2 >= R2 || border_[v]) continue;
    const double u = 1.0 - d2 / R2;
    kernel_vertex_[nw] = v;
    kernel_weight_[nw] = m_[v] * u * u;
    x0_[nw] = x_[v];
    sum += kernel_weight_[nw];
    ++nw;
  }
  if (sum <= 0.0) {
    nw = 0;
    for (int kk = 0; kk < 3; ++kk) {
      kernel_vertex_[nw] = t[kk];
      kernel_weight_[nw] = b[kk];
      x0_[nw] = x_[t[kk]];
      ++nw;
    }
  } else {
    for (int i = 0; i < nw; ++i) kernel_weight_[i] /= sum;
  }
  return K;
}

void LocalPatch::spring_forces() noexcept {
  for (int v = 0; v < nv_; ++v) f_[v].setZero();
  for (int e = 0; e < ne_; ++e) {
    const int i = edge_[e][0], j = edge_[e][1];
    const Vec3 d = x_[j] - x_[i];
    const double L = d.norm();
    if (L <= 0.0) continue;
    const Vec3 f = k_[e] * (L - rest_len_[e]) / L * d;
    f_[i] += f;
    f_[j] -= f;
  }
}

// One substep of the contact on the touched point: the normal spring (with damping) and the
// Coulomb friction spring to `anchor`. Their reaction is spread over the kernel's vertices;
// returns the force on the user's finger.
Vec3 LocalPatch::contact_forces(const PatchTouch& touch, const Kernel& K, Vec3& anchor,
                                Vec3& q_prev, bool& slipping) noexcept {
  const Vec3& c = touch.c;
  const double k = touch.k;
  Vec3 q = K.q0;
  for (int i = 0; i < K.n; ++i) q += kernel_weight_[i] * (x_[kernel_vertex_[i]] - x0_[i]);
  const Vec3& nn = K.n0;
  const double depth = touch.r - (c - q).dot(nn);
  // Normal spring plus damping of the touched point's motion relative to the fingertip: the
  // refined vertices are light, and the contact spring alone would ring at kHz.
  Vec3 vq = Vec3::Zero();
  for (int i = 0; i < K.n; ++i) vq += kernel_weight_[i] * v_[kernel_vertex_[i]];
  const double fn = depth > 0.0 ? std::max(0.0, k * depth + p_.contact_damping * (vq - touch.vc).dot(nn)) : 0.0;
  // Friction: the anchor rides with the touched point; the spring to it sticks up to mu fn.
  anchor += q - q_prev;
  q_prev = q;
  Vec3 d = anchor - c;
  d -= d.dot(nn) * nn;
  Vec3 ft = k * d;
  const double lim = touch.mu * fn, ftn = ft.norm();
  if (ftn > lim) {
    ft *= ftn > 0.0 ? lim / ftn : 0.0;
    slipping = true;
  }
  anchor = c + ft / k + (anchor - c).dot(nn) * nn;
  const Vec3 Fu = fn * nn + ft;  // on the user's finger
  for (int i = 0; i < K.n; ++i) f_[kernel_vertex_[i]] -= kernel_weight_[i] * Fu;
  return Fu;
}

// Symplectic Euler for the interior, damped towards the cloth's own motion; the border moves
// with its velocity.
void LocalPatch::integrate(const ClothSnapshot& s, double h) noexcept {
  for (int v = 0; v < nv_; ++v) {
    if (border_[v]) {
      x_[v] += h * v_[v];
      continue;
    }
    const Vec3 vg = 0.5 * (s.v[edge_end_a_[v]] + s.v[edge_end_b_[v]]);
    v_[v] += h * (f_[v] / m_[v] - p_.damping * (v_[v] - vg));
    x_[v] += h * v_[v];
  }
}

SurfacePoint LocalPatch::closest(const Vec3& p) const noexcept {
  SurfacePoint best;
  for (int t = 0; t < nt_; ++t) {
    const auto& tr = tri_[t];
    const ClosestPoint cp = closest_point_triangle(p, x_[tr[0]], x_[tr[1]], x_[tr[2]]);
    if (cp.dist2 < best.dist2) {
      best.dist2 = cp.dist2;
      best.point = cp.point;
      best.triangle = t;
      for (int k = 0; k < 3; ++k) best.bary[k] = cp.b[k];
    }
  }
  if (best.triangle >= 0) {
    const auto& tr = tri_[best.triangle];
    Vec3 n = Vec3::Zero(), v = Vec3::Zero();
    for (int k = 0; k < 3; ++k) {
      n += best.bary[k] * n_[tr[k]];
      v += best.bary[k] * v_[tr[k]];
    }
    const double l = n.norm();
    best.normal = l > 0 ? Vec3(n / l) : Vec3::UnitZ();
    best.velocity = v;
  }
  return best;
}

}  // namespace hapticloth::haptics
