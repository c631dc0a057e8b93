// The step (eqs. 8-9): its table of contents, the attempt and its retries, the solve and the
// acceptance. Assembly, the springs and proxies, the active set and the blow-up guard are in
// integrator_assembly.cpp, integrator_springs.cpp, integrator_contacts.cpp and
// integrator_guard.cpp.
#include "cloth/integrator.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <numeric>
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
  if (assembly_threads < 1 || assembly_threads > 2) bad("threads", "must be 1 or 2");
  if (!(explosion_ratio > 0.0)) bad("explosion_ratio", "must be > 0");
  if (!(matrix_refresh >= 0.0 && matrix_refresh < 1.0)) bad("matrix_refresh", "must be in [0, 1)");
  if (simd && !runs_here(*simd))
    bad("simd", std::string(to_string(*simd)) + " is not an instruction level this CPU runs (it runs " +
                    to_string(best_level()) + ")");
}

Integrator::Integrator(const ClothModel& model, const IntegratorConfig& config,
                       std::unique_ptr<LinearSolver> solver)
    : model_(model), cfg_(config), solver_(std::move(solver)) {
  cfg_.validate();
  alpha_ = cfg_.alpha;
  if (!solver_) throw std::invalid_argument("integrator: a linear solver is required");
  viscous_ = model_.material.viscous();
  if (cfg_.proxies < 0 || cfg_.proxies > 16)
    throw std::invalid_argument("integrator.proxies: must be in [0, 16]");
  sys_ = build_pattern(model_, cfg_.proxies);
  const ElementKernels& kernels = element_kernels(cfg_.element_level());
  simd_ = kernels.level;
  lanes_ = kernels.lanes;
  std::vector<std::vector<int>> parts;  // the element pass's parts, the caller's alone last
  if (cfg_.assembly_threads > 1 && model_.num_triangles() >= kMinParallelElements) {
    // Four parts for two threads: whichever thread is free takes the next, so a helper that
    // wakes late (or is preempted) costs part of a part, not half the assembly.
    const ElementPartition partition = partition_elements(model_.elements, model_.rest_positions, 4);
    parts = partition.parts;
    parts.push_back(partition.separators);
    part_energy_.assign(partition.parts.size(), ClothEnergy{});
    plan_clearing(partition);
    pool_ = std::make_unique<WorkerPool>();
    solver_->use_pool(pool_.get());
  } else {
    parts.emplace_back(model_.num_triangles());
    std::iota(parts[0].begin(), parts[0].end(), 0);
    part_free_.assign(1, std::vector<int>(model_.num_free()));
    std::iota(part_free_[0].begin(), part_free_[0].end(), 0);
  }
  pass_ = kernels.make_pass(model_.elements, parts);
  kept_ = std::make_unique<KeptMatrix>(cfg_.matrix_refresh, static_cast<int>(parts.size()), sys_.csr.n / 3);
  part_refreshed_.assign(parts.size(), 0);
  A_ = sys_.csr;
  double m2 = 0.0;
  for (int v : model_.free_vertices) m2 += model_.mass[v] * model_.mass[v];
  free_mass_norm_ = std::sqrt(m2);
  proxies_.assign(cfg_.proxies, ProxyNode{});
  const int n = A_.n;
  rhs_.setZero(n);
  dv_.setZero(n);
  dv_prev_.setZero(n);
  guess_.setZero(n);
  dv_from_.setZero(n);
  dv_full_.setZero(n);
  delta_.setZero(n);
  a_delta_.setZero(n);
  ls_terms_.reserve(4096);
  released_.reserve(4096);
  spring_rows_.reserve(n / 3);
  spring_row_marked_.assign(n / 3, 0);
  const int nv = model_.num_vertices();
  f_ext_.assign(nv, Vec3::Zero());
  k_ext_.assign(nv, Mat3::Zero());
  k_ext_in_matrix_.assign(nv, Mat3::Zero());
  xn_.assign(nv, Vec3::Zero());
  vn_.assign(nv, Vec3::Zero());
  x_start_.assign(nv, Vec3::Zero());
  x_before_.assign(nv, Vec3::Zero());
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

// Eq. 9 update of a solved (sub)step into the candidate state: dv from the solve,
// dx = h (v + alpha dv); pinned vertices move with their velocity, proxies by alpha h dv_p.
void Integrator::candidate_state(const ClothState& s, double h) {
  const double a = alpha_;
  for (int i = 0; i < model_.num_vertices(); ++i) {
    const int f = model_.free_index[i];
    if (f < 0) {
      vn_[i] = s.v[i];
      xn_[i] = s.x[i] + h * s.v[i];
      continue;
    }
    const Vec3 dv = dv_.segment<3>(3 * f);
    vn_[i] = s.v[i] + dv;
    xn_[i] = s.x[i] + h * (s.v[i] + a * dv);
  }
  for (int j = 0; j < cfg_.proxies; ++j)
    proxies_[j].displacement = a * h * dv_.segment<3>(3 * (sys_.free_nodes + j));
}

const SymCsr& Integrator::system_matrix(const ClothState& s, double h, JacobianMode mode) {
  kept_->invalidate();  // formed whole
  assemble(s, h, mode);
  return A_;
}

// One (sub)step of eq. 9 that either is accepted into `s` or fails with its cause counted.
Integrator::Attempt Integrator::single_step(ClothState& s, double h) {
  last_h_ = h;
  solver_->set_residual_scale(weight_impulse(h));
  // The helper thread spins from the assembly to the last re-solve: a solve's iterations share
  // two short runs each with it, which a futex wake per run would cost more than they save.
  const WorkerPool::Burst burst(pool_.get());
  const auto t0 = Clock::now();
  if (!assemble(s, h, cfg_.jacobian)) {
    ++events_.non_finite;
    return Attempt::Failed;
  }
  timing_.assemble_ms += ms_since(t0);
  if (slow_blow_up(h)) return Attempt::Failed;
  if (!solve(s, h)) return Attempt::Failed;
  candidate_state(s, h);
  if (!revise_contacts(s, h)) return Attempt::Failed;
  double work = 0.0;
  if (energy_explosion(s, work)) return Attempt::Failed;
  accept(s, h, work);
  return Attempt::Ok;
}

// Eq. 9 for dv, warm-started from the last two solutions extrapolated linearly (dv changes
// smoothly in time). Where the exact Hessian is indefinite (compression or large shear) the step
// is assembled again with the positive semi-definite one. False, with the cause counted, if the
// solver fails or dv is not finite.
bool Integrator::solve(const ClothState& s, double h) {
  const auto t1 = Clock::now();
  guess_ = 2.0 * dv_ - dv_prev_;
  dv_prev_ = dv_;
  dv_ = guess_;
  // A kept matrix whose changes reach few rows: the solver reloads those (a quarter of them is
  // about where reloading row by row costs what the whole copy on the pool's threads does).
  const std::vector<int>& changed = kept_->take_changed_rows();
  const bool reload_changed = assembled_kept_ && solver_synced_ && 4 * changed.size() <= static_cast<size_t>(A_.n / 3);
  SolveStatus st = reload_changed ? solver_->solve_changed(A_, changed.data(), static_cast<int>(changed.size()),
                                                           rhs_.data(), dv_.data())
                                  : solver_->solve(A_, rhs_.data(), dv_.data());
  if (reload_changed) timing_.changed_rows = static_cast<int>(changed.size());
  solver_synced_ = st == SolveStatus::Ok;
  timing_.iterations += solver_->iterations();
  if (st == SolveStatus::NotPositiveDefinite && cfg_.jacobian == JacobianMode::Exact) {
    ++events_.jacobian_fallbacks;
    const auto t2 = Clock::now();
    assemble(s, h, JacobianMode::Spd);
    timing_.assemble_ms += ms_since(t2);
    dv_.setZero();
    kept_->take_changed_rows();
    st = solver_->solve(A_, rhs_.data(), dv_.data());
    solver_synced_ = st == SolveStatus::Ok;
    timing_.iterations += solver_->iterations();
  }
  timing_.solve_ms += ms_since(t1);
  return resolved(st);
}

// The candidate state becomes the state; the energy balance remembers this step.
void Integrator::accept(ClothState& s, double h, double work) {
  last_work_ = work;
  if (have_prev_energy_) excess_energy_ = pending_excess_;
  prev_energy_ = energy_old_;
  have_prev_energy_ = true;
  s.x.swap(xn_);
  s.v.swap(vn_);
  for (auto& p : proxies_) p.x += p.displacement;
  s.time += h;
  ++timing_.substeps;
}

Integrator::Attempt Integrator::advance(ClothState& s, double h, int depth) {
  const std::uint64_t explosions = events_.energy_explosions;
  if (single_step(s, h) == Attempt::Ok) return Attempt::Ok;
  if (depth >= cfg_.max_halvings) return Attempt::Failed;
  ++events_.retries;
  // An energy explosion at alpha < 1 (little numerical damping: the step can ring with a stiff
  // law; hapticloth-bench stability, alpha 0.5 at 1000x denim) is retried with backward Euler
  // (alpha 1, L-stable), which the integrator keeps from then on: counted, never silent.
  if (events_.energy_explosions > explosions && alpha_ < 1.0) {
    alpha_ = 1.0;
    ++events_.alpha_fallbacks;
  }
  if (advance(s, 0.5 * h, depth + 1) == Attempt::Failed) return Attempt::Failed;
  return advance(s, 0.5 * h, depth + 1);
}

StepOutcome Integrator::step(ClothState& s) {
  const auto t0 = Clock::now();
  timing_ = StepTiming{};
  const std::int64_t wait0 = pool_ ? pool_->caller_wait_ns() : 0;
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
    excess_energy_ = 0.0;
    have_prev_energy_ = false;
    timing_.total_ms = ms_since(t0);
    return StepOutcome::Restored;
  }
  x_before_.swap(x_start_);  // the start of the previous step (no copy)
  for (int i = 0; i < model_.num_vertices(); ++i) {
    x_start_[i] = s.x[i];
    v_start_[i] = s.v[i];
  }
  const double t_start = s.time;
  StepOutcome out = StepOutcome::Accepted;
  blown_up_ = false;
  if (advance(s, cfg_.dt, 0) == Attempt::Failed) {
    ++events_.restores;
    // A blow-up found by the energy balance is seen one step late: the state at the start of
    // this step already carries it, so go back one step further.
    const std::vector<Vec3>& good = blown_up_ && have_before_ ? x_before_ : x_start_;
    for (int i = 0; i < model_.num_vertices(); ++i) {
      s.x[i] = model_.pinned[i] ? x_start_[i] : good[i];
      s.v[i] = model_.pinned[i] ? v_start_[i] : Vec3::Zero();
    }
    dv_.setZero();
    dv_prev_.setZero();
    excess_energy_ = 0.0;
    have_prev_energy_ = false;
    out = StepOutcome::Restored;
  }
  have_before_ = true;
  s.time = t_start + cfg_.dt;
  if (pool_) timing_.helper_wait_ms = 1e-6 * static_cast<double>(pool_->caller_wait_ns() - wait0);
  timing_.total_ms = ms_since(t0);
  return out;
}

}  // namespace hapticloth::cloth
