#include "cloth/integrator.hpp"

#include <chrono>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>

namespace hapticloth::cloth {

namespace {
using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}
}  // namespace

void IntegratorConfig::validate() const {
  auto bad = [](const std::string& f, const std::string& why) {
    throw std::invalid_argument("integrator." + f + ": " + why);
  };
  if (!(dt > 0.0) || !std::isfinite(dt)) bad("dt", "must be a positive number of seconds");
  if (!(alpha >= 0.5 && alpha <= 1.0)) bad("alpha", "must be in [0.5, 1] (eq. 8)");
  if (!gravity.allFinite()) bad("gravity", "must be finite");
  if (!(air_damping >= 0.0) || !std::isfinite(air_damping)) bad("air_damping", "must be >= 0");
  if (max_halvings < 0 || max_halvings > 20) bad("max_halvings", "must be in [0, 20]");
  if (!(explosion_ratio > 0.0)) bad("explosion_ratio", "must be > 0");
}

Integrator::Integrator(const ClothModel& model, const IntegratorConfig& config,
                       std::unique_ptr<LinearSolver> solver)
    : model_(model), cfg_(config), solver_(std::move(solver)) {
  cfg_.validate();
  if (!solver_) throw std::invalid_argument("integrator: a linear solver is required");
  viscous_ = model_.material.viscous();
  A_ = model_.pattern;
  const int n = A_.n;
  rhs_.setZero(n);
  dv_.setZero(n);
  dv_prev_.setZero(n);
  guess_.setZero(n);
  const int nv = model_.num_vertices();
  f_ext_.assign(nv, Vec3::Zero());
  xn_.assign(nv, Vec3::Zero());
  vn_.assign(nv, Vec3::Zero());
  x_start_.assign(nv, Vec3::Zero());
  v_start_.assign(nv, Vec3::Zero());
  if (n > 0) solver_->analyze(A_);

  // Energy floor of the explosion test: the potential energy of the cloth over its own size,
  // plus the elastic energy of a 5% deformation in every mode.
  Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
  for (const auto& p : model_.rest_positions) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double size = nv ? (hi - lo).norm() : 0.0;
  const auto& m = model_.material;
  energy_floor_ = model_.total_mass * std::max(cfg_.gravity.norm(), 1.0) * size +
                  model_.total_area * (m.weft.energy(0.05) + m.warp.energy(0.05) +
                                       m.shear.energy(0.05)) +
                  1e-12;
}

bool Integrator::state_finite(const ClothState& s) const {
  for (int i = 0; i < model_.num_vertices(); ++i)
    if (!s.x[i].allFinite() || !s.v[i].allFinite()) return false;
  return true;
}

bool Integrator::assemble(const ClothState& s, double h, JacobianMode mode) {
  const double a = cfg_.alpha, ah = a * h, aahh = a * a * h * h;
  std::memset(A_.val.data(), 0, sizeof(double) * A_.val.size());
  rhs_.setZero();
  EvalRequest req;
  req.hessian = true;
  req.blocks = false;  // the factored Jacobians are enough (see ElementEval)
  req.mode = mode;
  ElementEval ev;
  double e_el = 0.0;
  Mat3 Ps, Qs, Ws, blk;
  const auto& els = model_.elements;
  for (size_t t = 0; t < els.size(); ++t) {
    const ElementRest& e = els[t];
    const Vec3* x[3] = {&s.x[e.v[0]], &s.x[e.v[1]], &s.x[e.v[2]]};
    const Vec3* v[3] = {&s.v[e.v[0]], &s.v[e.v[1]], &s.v[e.v[2]]};
    evaluate_element(e, model_.material, x, viscous_ ? v : nullptr, req, ev);  // eqs. 3-7
    e_el += ev.energy;
    // H v per vertex from the factored form: sum_l H_kl v_l = ru_k (P Uv + W Vv) + rv_k (Q Vv + W^T Uv)
    const Vec3 Uv = e.ru[0] * *v[0] + e.ru[1] * *v[1] + e.ru[2] * *v[2];
    const Vec3 Vv = e.rv[0] * *v[0] + e.rv[1] * *v[1] + e.rv[2] * *v[2];
    const Vec3 hu = ev.P * Uv + ev.W * Vv, hv = ev.Q * Vv + ev.W.transpose() * Uv;
    // System blocks alpha^2 h^2 H_kl + alpha h C_kl share the factored form.
    Ps = aahh * ev.P;
    Qs = aahh * ev.Q;
    Ws = aahh * ev.W;
    if (viscous_) {
      Ps += ah * ev.Pc;
      Qs += ah * ev.Qc;
      Ws += ah * ev.Wc;
    }
    const auto& off = model_.block_offset[t];
    for (int k = 0; k < 3; ++k) {
      const int fk = model_.free_index[e.v[k]];
      if (fk < 0) continue;
      // Right-hand side of eq. 9: h (F - alpha h H v); H v includes pinned neighbours, which
      // is how their prescribed motion enters the solve.
      rhs_.segment<3>(3 * fk) += h * (ev.f[k] - ah * (e.ru[k] * hu + e.rv[k] * hv));
      const int stride = model_.row_stride[fk];
      for (int l = 0; l < 3; ++l) {
        const int o = off[k * 3 + l];
        if (o < 0) continue;
        combine_blocks(blk, e.ru[k] * e.ru[l], Ps, e.rv[k] * e.rv[l], Qs, e.ru[k] * e.rv[l], Ws,
                       e.rv[k] * e.ru[l]);
        double* dst = A_.val.data() + o;
        for (int r = 0; r < 3; ++r, dst += stride)
          for (int c = 0; c < 3; ++c) dst[c] += blk(r, c);
      }
    }
  }
  // Lumped mass, air damping, gravity and external forces on free vertices.
  double ke = 0.0, eg = 0.0;
  const double cair = cfg_.air_damping;
  for (int f = 0; f < model_.num_free(); ++f) {
    const int i = model_.free_vertices[f];
    const double mi = model_.mass[i];
    const double ci = cair * model_.vertex_area[i];
    double* dst = A_.val.data() + model_.diag_offset[f];
    const int stride = model_.row_stride[f];
    for (int r = 0; r < 3; ++r) dst[r * stride + r] += mi + ah * ci;
    rhs_.segment<3>(3 * f) += h * (mi * cfg_.gravity - ci * s.v[i] + f_ext_[i]);
    ke += 0.5 * mi * s.v[i].squaredNorm();
    eg -= mi * cfg_.gravity.dot(s.x[i]);
  }
  energy_old_ = ke + e_el + eg;
  energy_scale_ = ke + std::abs(e_el) + energy_floor_;
  return rhs_.allFinite() && std::isfinite(energy_old_);
}

const SymCsr& Integrator::system_matrix(const ClothState& s, double h, JacobianMode mode) {
  assemble(s, h, mode);
  return A_;
}

Integrator::Attempt Integrator::single_step(ClothState& s, double h) {
  auto t0 = Clock::now();
  JacobianMode mode = cfg_.jacobian;
  if (!assemble(s, h, mode)) {
    ++events_.non_finite;
    return Attempt::Failed;
  }
  timing_.assemble_ms += ms_since(t0);

  auto t1 = Clock::now();
  // Warm start: extrapolate the last two solutions linearly (dv changes smoothly in time).
  guess_ = 2.0 * dv_ - dv_prev_;
  dv_prev_ = dv_;
  dv_ = guess_;
  SolveStatus st = solver_->solve(A_, rhs_.data(), dv_.data());
  timing_.iterations += solver_->iterations();
  if (st == SolveStatus::NotPositiveDefinite && mode == JacobianMode::Exact) {
    // The exact Hessian is indefinite here (compression or large shear): fall back to the
    // positive semi-definite one for this step.
    ++events_.jacobian_fallbacks;
    mode = JacobianMode::Spd;
    auto t2 = Clock::now();
    assemble(s, h, mode);
    timing_.assemble_ms += ms_since(t2);
    dv_.setZero();
    st = solver_->solve(A_, rhs_.data(), dv_.data());
    timing_.iterations += solver_->iterations();
  }
  timing_.solve_ms += ms_since(t1);
  if (st != SolveStatus::Ok) {
    switch (st) {
      case SolveStatus::NotConverged: ++events_.solver_not_converged; break;
      case SolveStatus::NotPositiveDefinite: ++events_.not_positive_definite; break;
      default: ++events_.solver_error; break;
    }
    dv_.setZero();
    dv_prev_.setZero();
    return Attempt::Failed;
  }
  if (!dv_.allFinite()) {
    dv_prev_.setZero();
    ++events_.non_finite;
    dv_.setZero();
    return Attempt::Failed;
  }

  // Eq. 9 update: dv from the solve, dx = h (v + alpha dv).
  const double a = cfg_.alpha;
  double ke = 0.0, eg = 0.0, work = 0.0;
  for (int i = 0; i < model_.num_vertices(); ++i) {
    const int f = model_.free_index[i];
    if (f < 0) {
      vn_[i] = s.v[i];
      xn_[i] = s.x[i] + h * s.v[i];
      continue;
    }
    const Vec3 dv = dv_.segment<3>(3 * f);
    const Vec3 dx = h * (s.v[i] + a * dv);
    vn_[i] = s.v[i] + dv;
    xn_[i] = s.x[i] + dx;
    ke += 0.5 * model_.mass[i] * vn_[i].squaredNorm();
    eg -= model_.mass[i] * cfg_.gravity.dot(xn_[i]);
    work += f_ext_[i].dot(dx);
  }
  // Energy explosion: the step created far more energy than external forces supplied. The
  // elastic energy is >= 0 (Psi >= 0 for laws through the origin), so kinetic + gravitational
  // energy is a lower bound of the new total and no second pass over the elements is needed:
  // a blow-up always shows in the velocities.
  const double e_new_lower = ke + eg;
  if (!std::isfinite(e_new_lower)) {
    ++events_.non_finite;
    return Attempt::Failed;
  }
  if (e_new_lower - energy_old_ - work > cfg_.explosion_ratio * energy_scale_) {
    ++events_.energy_explosions;
    return Attempt::Failed;
  }
  s.x.swap(xn_);
  s.v.swap(vn_);
  s.time += h;
  ++timing_.substeps;
  return Attempt::Ok;
}

Integrator::Attempt Integrator::advance(ClothState& s, double h, int depth) {
  if (single_step(s, h) == Attempt::Ok) return Attempt::Ok;
  if (depth >= cfg_.max_halvings) return Attempt::Failed;
  ++events_.retries;
  if (advance(s, 0.5 * h, depth + 1) == Attempt::Failed) return Attempt::Failed;
  return advance(s, 0.5 * h, depth + 1);
}

StepOutcome Integrator::step(ClothState& s) {
  const auto t0 = Clock::now();
  timing_ = StepTiming{};
  if (!state_finite(s)) {
    // Someone handed us a broken state: go back to the start of the last step, at rest.
    ++events_.non_finite;
    ++events_.restores;
    for (int i = 0; i < model_.num_vertices(); ++i) {
      s.x[i] = x_start_[i];
      s.v[i] = model_.pinned[i] && v_start_[i].allFinite() ? v_start_[i] : Vec3::Zero();
    }
    if (!state_finite(s)) {  // nothing good yet: the rest shape
      s.x = model_.rest_positions;
      for (auto& v : s.v) v.setZero();
    }
    dv_.setZero();
    dv_prev_.setZero();
    timing_.total_ms = ms_since(t0);
    return StepOutcome::Restored;
  }
  for (int i = 0; i < model_.num_vertices(); ++i) {
    x_start_[i] = s.x[i];
    v_start_[i] = s.v[i];
  }
  const double t_start = s.time;
  StepOutcome out = StepOutcome::Accepted;
  if (advance(s, cfg_.dt, 0) == Attempt::Failed) {
    ++events_.restores;
    for (int i = 0; i < model_.num_vertices(); ++i) {
      s.x[i] = x_start_[i];
      s.v[i] = model_.pinned[i] ? v_start_[i] : Vec3::Zero();
    }
    dv_.setZero();
    dv_prev_.setZero();
    out = StepOutcome::Restored;
  }
  s.time = t_start + cfg_.dt;
  timing_.total_ms = ms_since(t0);
  return out;
}

}  // namespace hapticloth::cloth
