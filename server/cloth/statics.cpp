#include "cloth/statics.hpp"

#include <cmath>

namespace hapticloth::cloth {

namespace {
IntegratorConfig newton_config(const Vec3& g, double h) {
  IntegratorConfig c;
  c.dt = h;
  c.alpha = 1.0;
  c.gravity = g;
  c.air_damping = 0.0;
  c.jacobian = JacobianMode::Spd;
  return c;
}
}  // namespace

StaticSolver::StaticSolver(const ClothModel& model, const Vec3& gravity)
    : model_(model),
      gravity_(gravity),
      integ_(model, newton_config(gravity, StaticOptions{}.regularization_step),
             make_cholmod_solver()),
      chol_(make_cholmod_solver()) {
  chol_->analyze(model_.pattern);
  f_ext_.assign(model_.num_vertices(), Vec3::Zero());
  f_.assign(model_.num_vertices(), Vec3::Zero());
  dx_.setZero(3 * model_.num_free());
}

double StaticSolver::energy(const ClothState& s) const {
  const Energies e = compute_energies(model_, s, gravity_);
  double w = 0.0;
  for (int i = 0; i < model_.num_vertices(); ++i) w += f_ext_[i].dot(s.x[i]);
  return e.elastic + e.gravity - w;
}

void StaticSolver::net_forces(const ClothState& s, std::vector<Vec3>& f) const {
  f.assign(model_.num_vertices(), Vec3::Zero());
  EvalRequest req;
  req.hessian = false;
  ElementEval ev;
  for (const auto& e : model_.elements) {
    const Vec3* x[3] = {&s.x[e.v[0]], &s.x[e.v[1]], &s.x[e.v[2]]};
    evaluate_element(e, model_.material, x, nullptr, req, ev);  // eqs. 3-7
    for (int k = 0; k < 3; ++k) f[e.v[k]] += ev.f[k];
  }
  for (int i = 0; i < model_.num_vertices(); ++i) f[i] += model_.mass[i] * gravity_ + f_ext_[i];
}

StaticResult StaticSolver::solve(ClothState& s, const StaticOptions& opt) {
  StaticResult res;
  for (auto& v : s.v) v.setZero();
  const double h = opt.regularization_step;
  auto residual = [&](const ClothState& st) {
    net_forces(st, f_);
    double r = 0.0;
    for (int i = 0; i < model_.num_vertices(); ++i)
      if (!model_.pinned[i]) r = std::max(r, f_[i].cwiseAbs().maxCoeff());
    return r;
  };
  integ_.external_forces() = f_ext_;
  res.residual = residual(s);
  double e0 = energy(s);
  for (int it = 0; it < opt.max_iterations; ++it) {
    if (!std::isfinite(res.residual)) return res;
    if (res.residual <= opt.force_tolerance) {
      res.converged = true;
      return res;
    }
    // (M + h^2 H) dv = h F with v = 0 (eq. 9), and the Newton step dx = h dv.
    const SymCsr& A = integ_.system_matrix(s, h, JacobianMode::Spd);
    dx_.setZero();
    if (chol_->solve(A, integ_.system_rhs().data(), dx_.data()) != SolveStatus::Ok) return res;
    dx_ *= h;
    // Backtracking on the energy; near convergence the energy difference is at round-off,
    // so a step that lowers the residual is accepted too.
    double t = 1.0;
    bool accepted = false;
    for (int ls = 0; ls < 30 && !accepted; ++ls, t *= 0.5) {
      trial_ = s;
      for (int f = 0; f < model_.num_free(); ++f)
        trial_.x[model_.free_vertices[f]] += t * dx_.segment<3>(3 * f);
      const double e1 = energy(trial_);
      const double r1 = residual(trial_);
      if (std::isfinite(e1) && (e1 < e0 || r1 < res.residual)) {
        s.x.swap(trial_.x);
        e0 = e1;
        res.residual = r1;
        accepted = true;
      }
    }
    res.iterations = it + 1;
    if (!accepted) return res;
  }
  res.residual = residual(s);
  res.converged = res.residual <= opt.force_tolerance;
  return res;
}

}  // namespace hapticloth::cloth
