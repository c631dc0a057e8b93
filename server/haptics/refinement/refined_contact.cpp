#include "haptics/refinement/refined_contact.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "cloth/element.hpp"

namespace hapticloth::haptics {

namespace {
// The Newton matrix's mass term m / h^2 (as cloth::StaticSolver's): it keeps the matrix definite
// where a slack cloth has no stiffness, and changes the path, not the equilibrium.
constexpr double kRegularizationStep = 0.1;  // s
// A sphere not yet touching has no stiffness along its normal: this one (N/m) sets its first
// Newton step, and a step is never longer than a quarter of the radius.
constexpr double kFreeSphereStiffness = 10.0;
// Settled once no vertex and no sphere has more net force left than this fraction of the
// largest fingertip force (1e-5: the compliance to 0.001%), or than kForceFloor N.
constexpr double kForceTolerance = 1e-5;
constexpr double kForceFloor = 1e-8;

struct Touch {  // a vertex inside sphere f: depth d, unit m from the centre, law phi', phi''
  double d, f1, f2;
  Vec3 m;
};
bool touch(const Vec3& x, const Vec3& centre, double area, const ChildLaw& law, Touch& t) {
  const Vec3 r = x - centre;
  const double len = r.norm();
  t.d = law.radius - len;
  if (t.d <= 0.0 || len <= 0.0) return false;
  t.m = r / len;
  const double ak = area * law.pressure_stiffness;
  t.f1 = ak * (t.d + t.d * t.d / law.stiffening_depth);
  t.f2 = ak * (1.0 + 2.0 * t.d / law.stiffening_depth);
  return true;
}
double law_energy(double d, double area, const ChildLaw& law) {
  return area * law.pressure_stiffness * (0.5 * d * d + d * d * d / (3.0 * law.stiffening_depth));
}
}  // namespace

RefinedContact::RefinedContact(RefinedMesh mesh, const cloth::Material& material,
                               const Vec3& gravity, const ChildLaw& law)
    : mesh_(std::move(mesh)),
      model_(cloth::build_model(mesh_.mesh, material, mesh_.held)),
      gravity_(gravity),
      law_(law) {
  build_pattern();
}

void RefinedContact::build_pattern() {
  const int nf = model_.num_free();
  A_ = model_.pattern;
  auto at = [&](int r, int c) {
    const int p = A_.find(r, c);
    if (p < 0) throw std::logic_error("refined contact: entry outside the pattern");
    return p;
  };
  elem_at_.assign(81 * model_.elements.size(), -1);
  for (std::size_t t = 0; t < model_.elements.size(); ++t) {
    const auto& e = model_.elements[t];
    for (int k = 0; k < 3; ++k)
      for (int l = 0; l < 3; ++l) {
        const int a = model_.free_index[e.v[k]], b = model_.free_index[e.v[l]];
        if (a < 0 || b < 0) continue;
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) elem_at_[81 * t + 9 * (3 * k + l) + 3 * r + c] = at(3 * a + r, 3 * b + c);
      }
  }
  diag_at_.assign(9 * nf, -1);
  for (int a = 0; a < nf; ++a)
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) diag_at_[9 * a + 3 * r + c] = at(3 * a + r, 3 * a + c);
  chol_ = cloth::make_cholmod_solver();
  chol_->analyze(A_);
  B_.setZero(3 * nf, kMaxFingers);
  Y_.setZero(3 * nf, kMaxFingers);
  g_.setZero(3 * nf);
  dx_.setZero(3 * nf);
  y_.setZero(3 * nf);
}

void RefinedContact::follow(const std::vector<Vec3>& global_x) {
  const bool first = placed_.empty();
  std::vector<Vec3>& old = placed_before_;  // the last placement; no allocation after the first
  old.swap(placed_);
  mesh_.place(global_x, placed_);
  if (first) {
    x_ = placed_;
    return;
  }
  for (int i = 0; i < model_.num_vertices(); ++i)
    x_[i] = model_.pinned[i] ? placed_[i] : Vec3(x_[i] + (placed_[i] - old[i]));
}

double RefinedContact::energy(const std::vector<Vec3>& x,
                              const std::array<double, kMaxFingers>& s) const {
  double E = 0.0;
  for (const auto& e : model_.elements)
    E += cloth::element_energy(e, model_.material, x[e.v[0]], x[e.v[1]], x[e.v[2]]);
  for (int i = 0; i < model_.num_vertices(); ++i) E -= model_.mass[i] * gravity_.dot(x[i]);
  for (int f = 0; f < kMaxFingers; ++f) {
    if (!fing_[f].in) continue;
    const Vec3 c = fing_[f].centre - s[f] * fing_[f].normal;
    for (int i = 0; i < model_.num_vertices(); ++i) {
      const double d = law_.radius - (x[i] - c).norm();
      if (d > 0.0) E += law_energy(d, model_.vertex_area[i], law_);
    }
    E -= fing_[f].force * s[f];
  }
  return E;
}

// The gradient of E (g_) and its Newton matrix (K_) at (x, s); returns the largest entry of the
// gradient (the net force left, N).
double RefinedContact::assemble(const std::vector<Vec3>& x, const std::array<double, kMaxFingers>& s) {
  const int nf = model_.num_free();
  double* val = A_.val.data();
  std::fill(A_.val.begin(), A_.val.end(), 0.0);
  g_.setZero();
  cloth::EvalRequest req;
  cloth::ElementEval ev;
  for (std::size_t t = 0; t < model_.elements.size(); ++t) {
    const auto& e = model_.elements[t];
    const Vec3* xe[3] = {&x[e.v[0]], &x[e.v[1]], &x[e.v[2]]};
    cloth::evaluate_element(e, model_.material, xe, nullptr, req, ev);  // eqs. 3-7
    for (int k = 0; k < 3; ++k) {
      const int a = model_.free_index[e.v[k]];
      if (a < 0) continue;
      g_.segment<3>(3 * a) -= ev.f[k];
      for (int l = 0; l < 3; ++l) {
        const int* at = &elem_at_[81 * t + 9 * (3 * k + l)];
        if (at[0] < 0) continue;
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) val[at[3 * r + c]] += ev.H[k][l](r, c);
      }
    }
  }
  const double reg = 1.0 / (kRegularizationStep * kRegularizationStep);
  for (int a = 0; a < nf; ++a) {
    const int i = model_.free_vertices[a];
    g_.segment<3>(3 * a) -= model_.mass[i] * gravity_;
    for (int r = 0; r < 3; ++r) val[diag_at_[9 * a + 4 * r]] += model_.mass[i] * reg;
  }
  B_.setZero();
  double largest = 0.0;
  for (int f = 0; f < kMaxFingers; ++f) {
    gs_[f] = 0.0;
    C_[f] = 1.0;
    push_[f].setZero();
    if (!fing_[f].in) continue;
    const Vec3& n = fing_[f].normal;
    const Vec3 c = fing_[f].centre - s[f] * n;
    double gs = -fing_[f].force, kss = kFreeSphereStiffness;
    for (int i = 0; i < model_.num_vertices(); ++i) {
      Touch t;
      if (!touch(x[i], c, model_.vertex_area[i], law_, t)) continue;
      const double mn = t.m.dot(n);
      gs -= t.f1 * mn;
      push_[f] -= t.f1 * t.m;
      kss += t.f2 * mn * mn;
      const int a = model_.free_index[i];
      if (a < 0) continue;
      g_.segment<3>(3 * a) -= t.f1 * t.m;
      const Eigen::Matrix3d mm = t.f2 * t.m * t.m.transpose();
      for (int r = 0; r < 3; ++r)
        for (int q = 0; q < 3; ++q) val[diag_at_[9 * a + 3 * r + q]] += mm(r, q);
      B_.col(f).segment<3>(3 * a) += t.f2 * mn * t.m;
    }
    gs_[f] = gs;
    C_[f] = kss;
    largest = std::max(largest, std::abs(gs));
  }
  return std::max(largest, nf ? g_.cwiseAbs().maxCoeff() : 0.0);
}

// The Newton step of [A B; B^T C] (dx, ds) = -(g, gs), the spheres' ds from their Schur
// complement C - B^T A^-1 B (at most kMaxFingers x kMaxFingers), then dx.
bool RefinedContact::newton_step() {
  g_ = -g_;
  const bool ok = chol_->solve(A_, g_.data(), y_.data()) == cloth::SolveStatus::Ok;
  g_ = -g_;
  if (!ok) return false;
  std::array<int, kMaxFingers> on{};
  int n = 0;
  for (int f = 0; f < kMaxFingers; ++f)
    if (fing_[f].in) {
      on[n++] = f;
      if (chol_->resolve(A_, B_.col(f).data(), Y_.col(f).data()) != cloth::SolveStatus::Ok) return false;
    }
  Eigen::Matrix<double, kMaxFingers, kMaxFingers> S = Eigen::Matrix<double, kMaxFingers, kMaxFingers>::Identity();
  Eigen::Matrix<double, kMaxFingers, 1> r = Eigen::Matrix<double, kMaxFingers, 1>::Zero();
  for (int i = 0; i < n; ++i) {
    r[i] = -gs_[on[i]] - B_.col(on[i]).dot(y_);
    for (int j = 0; j < n; ++j) S(i, j) = (i == j ? C_[on[i]] : 0.0) - B_.col(on[i]).dot(Y_.col(on[j]));
  }
  const Eigen::Matrix<double, kMaxFingers, 1> z = S.ldlt().solve(r);
  ds_.fill(0.0);
  dx_ = y_;
  for (int i = 0; i < n; ++i) {
    ds_[on[i]] = std::clamp(z[i], -0.25 * law_.radius, 0.25 * law_.radius);
    dx_ -= ds_[on[i]] * Y_.col(on[i]);
  }
  return true;
}

double RefinedContact::settle(const std::array<ChildFinger, kMaxFingers>& fingers, int iterations) {
  for (int f = 0; f < kMaxFingers; ++f)
    if (!fingers[f].in || !fing_[f].in) s_[f] = 0.0;
  fing_ = fingers;
  const int nf = model_.num_free();
  double left = assemble(x_, s_);
  double scale = 0.0;
  for (const auto& f : fing_) scale = std::max(scale, f.in ? f.force : 0.0);
  const double tolerance = std::max(kForceTolerance * scale, kForceFloor);
  double E0 = energy(x_, s_);
  for (int it = 0; it < iterations && left > tolerance; ++it) {
    if (!newton_step()) break;
    double t = 1.0;
    bool accepted = false;
    for (int ls = 0; ls < 20 && !accepted; ++ls, t *= 0.5) {
      x_try_ = x_;
      for (int a = 0; a < nf; ++a) x_try_[model_.free_vertices[a]] += t * dx_.segment<3>(3 * a);
      for (int f = 0; f < kMaxFingers; ++f) s_try_[f] = s_[f] + t * ds_[f];
      const double E1 = energy(x_try_, s_try_);
      // Near the minimum E changes at its own round-off: accept within it.
      if (std::isfinite(E1) && E1 <= E0 + 1e-13 * std::abs(E0)) {
        x_.swap(x_try_);
        s_ = s_try_;
        E0 = E1;
        accepted = true;
      }
    }
    left = assemble(x_, s_);
    if (!accepted) break;
  }
  return left;
}

}  // namespace hapticloth::haptics
