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
// Re-solves of a step taken whole before the active set's line search (line_search_contacts)
// starts: a set that one re-solve settles, as in a slow stroke, is left to it. Searching from the
// first, the stroke's Coulomb error per contact went from p99 2.7% to 3.1% (its friction revised
// at the line search's points), while the cycling it is for takes many re-solves.
constexpr int kPlainRevisions = 1;
using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// Adds the 3x3 block B at `offset` of a CSR value array whose rows are `stride` apart.
inline void add_block(double* val, int offset, int stride, const Mat3& B) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) val[offset + r * stride + c] += B(r, c);
}

}  // namespace

// One pass over the cloth for eq. 9: the element pass (ElementPass, at the instruction level
// in use) forms each element's forces, factored Jacobian, system blocks
// alpha^2 h^2 H_kl + alpha h C_kl and right-hand side h (F - alpha h H v) into the CSR values;
// vertex_terms adds the vertices' own terms. `keep`: the matrix in hand is kept, and only the
// blocks of the elements whose factors moved are added, as the blocks of the factors' change
// (KeptMatrix). Returns the cloth's energies at the start of the step.
Integrator::ClothEnergy Integrator::assemble_cloth(const ClothState& s, double h, bool keep, bool spd) {
  const PassInput in{&model_.material, s.x.data(), s.v.data(), StepFactors{h, alpha_}, viscous_, spd};
  const PassTarget out{A_.val.data(), rhs_.data(), model_.free_index.data(), sys_.block_offset.data(),
                       sys_.row_stride.data()};
  const auto pass = [&](int part) { return pass_->run(part, in, out, *kept_, keep, part_refreshed_[part]); };
  const int rest = static_cast<int>(part_free_.size()) - 1;
  if (!pool_) {
    if (!keep) std::memset(A_.val.data(), 0, sizeof(double) * A_.val.size());
    const double elastic = pass(rest);
    ClothEnergy e = vertex_terms(s, h, rest, keep);
    e.elastic = elastic;
    return e;
  }
  // Two threads: the parts at once (disjoint rows), then the separators (the rest); the energy
  // summed in the same order whichever thread took a part. Each part's rows are cleared, and
  // its vertices' terms added, by the thread that assembles its elements, so that they are in
  // its core's cache (zero_spans_, part_free_); the caller takes the rest's first.
  if (!keep) clear_rows(zero_spans_.back());
  ClothEnergy e = vertex_terms(s, h, rest, keep);
  auto part = [&](int p) {
    if (!keep) clear_rows(zero_spans_[p]);
    const double elastic = pass(p);
    part_energy_[p] = vertex_terms(s, h, p, keep);
    part_energy_[p].elastic = elastic;
  };
  pool_->run(rest, part);
  for (const ClothEnergy& pe : part_energy_) {
    e.elastic += pe.elastic;
    e.kinetic += pe.kinetic;
    e.gravity += pe.gravity;
  }
  e.elastic += pass(rest);
  return e;
}

// Eq. 9's terms of the free vertices of assembly part `part` (part_free_): the lumped mass M
// and air damping on their diagonal blocks, h (M g - c v + f_ext) on their right-hand sides, and
// the external forces' stiffness where it is on. A kept matrix (`keep`) holds the mass and
// damping already, and takes only the external stiffness's change. Returns their kinetic and
// gravitational energy.
Integrator::ClothEnergy Integrator::vertex_terms(const ClothState& s, double h, int part, bool keep) {
  const double ah = alpha_ * h;
  const double cair = cfg_.air_damping;
  // f_ext(x + dx) ~ f_ext - K dx: K joins H in eq. 9 (alpha^2 h^2 K in the matrix, -alpha h^2 K v
  // on the right).
  const bool stiffness_terms = external_stiffness_on || (keep && k_ext_held_);
  ClothEnergy e;
  for (int f : part_free_[part]) {
    const int i = model_.free_vertices[f];
    const double mi = model_.mass[i];
    const double ci = cair * model_.vertex_area[i];
    double* dst = A_.val.data() + sys_.diag_offset[f];
    const int stride = sys_.row_stride[f];
    if (!keep)
      for (int r = 0; r < 3; ++r) dst[r * stride + r] += mi + ah * ci;
    rhs_.segment<3>(3 * f) += h * (mi * cfg_.gravity - ci * s.v[i] + f_ext_[i]);
    if (external_stiffness_on) rhs_.segment<3>(3 * f) -= ah * h * (k_ext_[i] * s.v[i]);
    if (stiffness_terms) {
      // What A_ holds of it: k_ext_in_matrix_ if it holds any (a kept matrix), else nothing.
      const Mat3 K = external_stiffness_on ? k_ext_[i] : Mat3::Zero();
      Mat3& held = k_ext_in_matrix_[i];
      const Mat3 dK = keep && k_ext_held_ ? Mat3(K - held) : K;
      held = K;
      if (!dK.isZero(0.0)) {
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) dst[r * stride + c] += ah * ah * dK(r, c);
        if (keep) kept_->mark(part, f);
      }
    }
    e.kinetic += 0.5 * mi * s.v[i].squaredNorm();
    e.gravity -= mi * cfg_.gravity.dot(s.x[i]);
  }
  return e;
}


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

void Integrator::clear_rows(const std::vector<std::pair<int, int>>& spans) {
  for (const auto& [begin, end] : spans) std::memset(A_.val.data() + begin, 0, sizeof(double) * (end - begin));
}

// zero_spans_: for each assembly part, the ranges of A_'s values in the rows its elements reach
// (no other part's reach them), and last the rest (the rows only separators reach, the proxies');
// part_free_: the free vertices of those rows, by part likewise.
void Integrator::plan_clearing(const ElementPartition& partition) {
  const SymCsr& A = sys_.csr;
  const int nb = A.n / 3;
  std::vector<int> owner(nb, -1);
  const int parts = static_cast<int>(partition.parts.size());
  for (int p = 0; p < parts; ++p)
    for (int t : partition.parts[p])
      for (int v : model_.elements[t].v)
        if (model_.free_index[v] >= 0) owner[model_.free_index[v]] = p;
  zero_spans_.assign(parts + 1, {});
  part_free_.assign(parts + 1, {});
  for (int f = 0; f < model_.num_free(); ++f) part_free_[owner[f] < 0 ? parts : owner[f]].push_back(f);
  for (int br = 0; br < nb; ++br) {
    auto& spans = zero_spans_[owner[br] < 0 ? parts : owner[br]];
    const int begin = A.rowptr[3 * br], end = A.rowptr[3 * br + 3];
    if (!spans.empty() && spans.back().second == begin)
      spans.back().second = end;
    else
      spans.push_back({begin, end});
  }
}

// f(row) for each block row the terms of `springs` reach (add_springs): their proxies' and
// their free corners', repeats included.
template <class F>
void Integrator::for_each_spring_row(const std::vector<PointSpring>& springs, F&& f) const {
  for (const PointSpring& sp : springs) {
    f(sys_.free_nodes + sp.proxy);
    for (int v : model_.elements[sp.tri].v)
      if (model_.free_index[v] >= 0) f(model_.free_index[v]);
  }
}

// Eq. 9 at state s for the (sub)step h: the matrix formed whole, or kept from the last
// assembly (KeptMatrix::keeps: the same h, alpha and mode) with the changes of the elements
// that moved, the external stiffness and the proxies' springs.
bool Integrator::assemble(const ClothState& s, double h, JacobianMode mode) {
  rhs_.setZero();
  const bool keep = kept_->keeps(h, alpha_, mode);
  if (keep) take_out_springs(h);
  const bool spd = mode == JacobianMode::Spd;
  const ClothEnergy e = assemble_cloth(s, h, keep, spd);
  for (int n : part_refreshed_) timing_.refreshed_elements += n;
  timing_.whole_assemblies += !keep;
  const double ke = e.kinetic, e_el = e.elastic, eg = e.gravity;
  energy_old_ = ke + e_el + eg;
  energy_scale_ = ke + std::abs(e_el) + energy_floor_;
  if (cfg_.proxies > 0) {
    assemble_proxies(s, h);
    if (keep) mark_proxy_rows();
  }
  k_ext_held_ = external_stiffness_on;
  springs_in_matrix_.assign(springs_.begin(), springs_.end());
  assembled_kept_ = keep;
  if (!keep) solver_synced_ = false;  // the solver's copy is of another matrix
  const bool ok = rhs_.allFinite() && std::isfinite(energy_old_);
  if (ok)
    kept_->assembled(h, alpha_, mode, !keep);
  else
    kept_->invalidate();
  return ok;
}

// A kept matrix holds the last assembly's proxies and point springs (springs_in_matrix_): their
// blocks in the proxies' rows and columns are set to zero (only they write there, so no rounding
// is left behind for the PCG's hub blocks to keep), and their corner blocks are taken back out
// of the cloth's. The rows they reach are marked changed.
void Integrator::take_out_springs(double h) {
  const double ah = alpha_ * h, aahh = ah * ah;
  const int nf = sys_.free_nodes, rest = static_cast<int>(part_free_.size()) - 1;
  double* const val = A_.val.data();
  const auto set_zero = [&](int offset, int stride) {
    for (int r = 0; r < 3; ++r) std::fill_n(val + offset + r * stride, 3, 0.0);
  };
  for (int j = 0; j < cfg_.proxies; ++j) set_zero(sys_.diag_offset[nf + j], sys_.row_stride[nf + j]);
  for (const PointSpring& sp : springs_in_matrix_) {
    const auto& e = model_.elements[sp.tri];
    const int node = nf + sp.proxy;
    const Mat3 Kh = -aahh * sp.K;
    const auto& off = sys_.block_offset[sp.tri];
    for (int k = 0; k < 3; ++k) {
      const int fk = model_.free_index[e.v[k]];
      if (fk < 0) continue;
      kept_->mark(rest, fk);
      set_zero(A_.rowptr[3 * fk] + sys_.row_stride[fk] - 3 * (cfg_.proxies - sp.proxy), sys_.row_stride[fk]);
      set_zero(A_.rowptr[3 * node] + 3 * fk, sys_.row_stride[node]);
      for (int l = 0; l < 3; ++l)
        if (off[k * 3 + l] >= 0) add_block(val, off[k * 3 + l], sys_.row_stride[fk], sp.b[k] * sp.b[l] * Kh);
    }
  }
}

// The rows a kept matrix's proxies and springs changed (assemble_proxies): every proxy's (its
// coupling is written anew) and the springs' free corners.
void Integrator::mark_proxy_rows() {
  const int nf = sys_.free_nodes, rest = static_cast<int>(part_free_.size()) - 1;
  for (int j = 0; j < cfg_.proxies; ++j) kept_->mark(rest, nf + j);
  for_each_spring_row(springs_, [&](int row) { kept_->mark(rest, row); });
}

// The proxies and point springs in eq. 9. A proxy is a node without mass or velocity of its own
// (quasi-static), so its unknown dv_p gives the displacement alpha h dv_p like a vertex at rest.
// Its coupling to the target (stiffness k, damping c) adds alpha^2 h^2 k + alpha h c to its
// diagonal and h (k (target - x) + c target_velocity) to its right-hand side. A point spring
// at x_q = sum b_k x_k with force f and stiffness K acts on the relative displacement of the
// point and the proxy: blocks alpha^2 h^2 b_k b_l K between corners, -alpha^2 h^2 b_k K between a
// corner and the proxy, alpha^2 h^2 K on the proxy; right-hand sides h b_k (f - alpha h K v_q)
// on the corners and minus their sum on the proxy.
void Integrator::assemble_proxies(const ClothState& s, double h) {
  const double ah = alpha_ * h, aahh = ah * ah;
  const int nf = sys_.free_nodes;
  double* const val = A_.val.data();
  for (int j = 0; j < cfg_.proxies; ++j) {
    const ProxyNode& p = proxies_[j];
    const int node = nf + j;
    const Mat3 K = p.stiffness_matrix();  // k I, or anisotropic along p.axis
    add_block(val, sys_.diag_offset[node], sys_.row_stride[node], aahh * K + ah * p.damping * Mat3::Identity());
    rhs_.segment<3>(3 * node) += h * (K * (p.target - p.x) + p.damping * p.target_velocity);
  }
  add_springs(s, h, springs_, 1.0);
}

// The point springs' terms of eq. 9, times `sign` (-1 takes a set back out before a re-solve).
void Integrator::add_springs(const ClothState& s, double h, const std::vector<PointSpring>& springs,
                             double sign) {
  const double ah = alpha_ * h, aahh = ah * ah;
  const int nf = sys_.free_nodes;
  double* const val = A_.val.data();
  for (const PointSpring& sp : springs) {
    const auto& e = model_.elements[sp.tri];
    const int node = nf + sp.proxy;
    Vec3 vq = Vec3::Zero();
    for (int k = 0; k < 3; ++k) vq += sp.b[k] * s.v[e.v[k]];
    const Vec3 g = sign * h * (sp.f - ah * (sp.K * vq));
    rhs_.segment<3>(3 * node) -= g;
    const Mat3 Kh = sign * aahh * sp.K;
    add_block(val, sys_.diag_offset[node], sys_.row_stride[node], Kh);
    const auto& off = sys_.block_offset[sp.tri];
    for (int k = 0; k < 3; ++k) {
      const int fk = model_.free_index[e.v[k]];
      if (fk < 0) continue;
      rhs_.segment<3>(3 * fk) += sp.b[k] * g;
      // corner row: the proxy's columns come last in it; the proxy's row lists every free node
      const int corner_proxy = A_.rowptr[3 * fk] + sys_.row_stride[fk] - 3 * (cfg_.proxies - sp.proxy);
      add_block(val, corner_proxy, sys_.row_stride[fk], -sp.b[k] * Kh);
      add_block(val, A_.rowptr[3 * node] + 3 * fk, sys_.row_stride[node], -sp.b[k] * Kh);
      for (int l = 0; l < 3; ++l)
        if (off[k * 3 + l] >= 0) add_block(val, off[k * 3 + l], sys_.row_stride[fk], sp.b[k] * sp.b[l] * Kh);
    }
  }
}

// The block rows that the springs' terms reach (add_springs): their proxies' and their free
// corners', each added once to spring_rows_.
void Integrator::mark_spring_rows(const std::vector<PointSpring>& springs) {
  for_each_spring_row(springs, [&](int row) {
    if (spring_row_marked_[row]) return;
    spring_row_marked_[row] = 1;
    spring_rows_.push_back(row);
  });
}

// Work done on the cloth by the point springs over the candidate step (their start-of-step
// forces on the displacement of their points): the user's energy input through the fingertips.
double Integrator::contact_work(const ClothState& s) const {
  double w = 0.0;
  for (const PointSpring& sp : springs_) {
    const auto& e = model_.elements[sp.tri];
    Vec3 dq = Vec3::Zero();
    for (int k = 0; k < 3; ++k) dq += sp.b[k] * (xn_[e.v[k]] - s.x[e.v[k]]);
    w += sp.f.dot(dq);
  }
  return w;
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

bool Integrator::proxy_response(std::vector<Mat3>& R) {
  const int P = cfg_.proxies, nf = sys_.free_nodes;
  R.assign(static_cast<size_t>(P) * P, Mat3::Zero());
  if (P == 0 || !(last_h_ > 0.0)) return false;
  if (response_.size() != static_cast<size_t>(3 * P)) {
    response_.assign(3 * P, Eigen::VectorXd::Zero(A_.n));
    unit_.setZero(A_.n);
  }
  const double h = last_h_, ah = alpha_ * h;
  const WorkerPool::Burst burst(pool_.get());  // 3 P solves in a row (as in single_step)
  // Unit right-hand sides: solved relative to |b| alone (single_step sets the weight's scale
  // again for the next step).
  solver_->set_residual_scale(0.0);
  for (int q = 0; q < P; ++q)
    for (int c = 0; c < 3; ++c) {
      // d b_q / d T_q = h k_q (the coupling's right-hand side), so d dv / d T_q = A^-1 h k_q e;
      // x_p = x0 + alpha h dv_p and v_p = dv_p then give R (see the header).
      const double scale = h * (ah * proxies_[q].stiffness + proxies_[q].damping);
      const int row = 3 * (nf + q) + c;
      Eigen::VectorXd& x = response_[3 * q + c];
      unit_[row] = 1.0;
      const SolveStatus st = solver_->resolve(A_, unit_.data(), x.data());
      unit_[row] = 0.0;
      if (st != SolveStatus::Ok || !x.allFinite()) {
        x.setZero();
        return false;
      }
      for (int p = 0; p < P; ++p) R[p * P + q].col(c) = scale * x.segment<3>(3 * (nf + p));
    }
  return true;
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

// |h M g| over the free vertices, N s: the right-hand side of eq. 9 for a cloth that starts to
// fall. The solves of a step stop at the solver's tolerance of the larger of this and their
// right-hand side. A cloth at rest has a right-hand side about a thousandth of this (the 4050-
// triangle square pinched at rest: 1.6e-3 at the median), and relative to that alone its solve
// would resolve forces a millionth of its weight. The residual so allowed is tolerance |g| |m|
// (2-norm over the vertices) as a force: 1.7e-5 N on the 4050-triangle square at 1e-3, against
// fingertip forces of 0.1-1.5 N. A cloth without gravity keeps the relative test.
double Integrator::weight_impulse(double h) const { return h * cfg_.gravity.norm() * free_mass_norm_; }

// A slow blow-up gains a fraction of the energy on every step, which the per-step test
// (energy_explosion, relative to the current energy) never sees. So the total energy at the start
// of this step (kinetic, elastic, gravitational: from the assembly) is compared with the previous
// step's plus the external work done in it, and the energy created is summed with a 0.1 s memory
// (a stable step creates none on a linear problem; the one linearized solve per step of a
// stiffening law creates some at large steps: 3-10x the floor when the hanging square is
// released at dt 40 ms, which then comes to rest); past 10x the energy floor it is an
// explosion (hapticloth-bench stability: alpha 0.5 with a stiff material).
bool Integrator::slow_blow_up(double h) {
  if (!have_prev_energy_) return false;
  const double gain = energy_old_ - prev_energy_ - last_work_;
  const double excess = excess_energy_ * std::exp(-h / 0.1) + std::max(0.0, gain);
  if (excess > 10.0 * cfg_.explosion_ratio * energy_floor_) {
    ++events_.energy_explosions;
    blown_up_ = true;
    return true;
  }
  pending_excess_ = excess;  // kept when the step is accepted
  return false;
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

// Active set: a contact that would pull or a point that would pass into a fingertip changes the
// point springs; the step is solved again with them (warm-started from the last solution),
// telling the solver which block rows the change touched, and the re-solve is taken as far as
// the line search allows. The step ends at a solve (the last re-solve taken whole), so the
// massless proxies are in exact force balance: what the device renders is what the cloth got.
// A short step whose solver can settle its contacts' rows alone (LinearSolver::
// settle_changed: the proxies and the vertices they hold, the rest of the cloth held) revises
// on those settles instead, and once the contacts ask for nothing more, solves the whole cloth
// from there and asks them again (confirm_settled). Each whole re-solve of a pinch's release
// cost about as many iterations as the step's first solve, 5-17, spent on the cloth far from
// the fingers, while the contacts' decisions are made on the rows they hold
// (docs/performance.md, "Contacts revised on local settles"). Such a step has no line search:
// a settle moves only those rows, so it cannot throw the whole cloth clear of a fingertip as a
// whole re-solve can, and the cycling the search stops is left to the free revisions' bound
// (FingertipContact::revise); the random two-finger runs' deepest point stays 0.33-0.41 mm.
bool Integrator::revise_contacts(const ClothState& s, double h) {
  released_.clear();
  bool cut = false;  // dv_ is the line search's point short of the re-solve dv_full_
  bool same = false;  // the last re-solve left dv_ as it was (it took no iteration)
  bool unconfirmed = false;  // dv_ is a settle's: the cloth away from the contacts not solved since
  // Direct coupling's short steps revise their contacts on local settles, confirmed by a whole
  // solve; the multirate path's long ones solve whole.
  const bool settles = cfg_.contact_steps == ContactSteps::Short && solver_->settles_locally();
  for (int rev = 0; contacts_ && rev < cfg_.max_contact_revisions; ++rev) {
    springs_solved_.assign(springs_.begin(), springs_.end());
    if (!contacts_->revise(xn_, proxies_, cut, same)) {
      if (!unconfirmed) break;
      if (!confirm_settled(s, h, same)) return false;
      unconfirmed = cut = false;
      continue;  // the contacts asked again, on the whole solve
    }
    ++events_.contact_revisions;
    dv_from_ = dv_;
    const auto t3 = Clock::now();
    add_springs(s, h, springs_solved_, -1.0);
    add_springs(s, h, springs_, 1.0);
    springs_in_matrix_.assign(springs_.begin(), springs_.end());
    spring_rows_.clear();
    mark_spring_rows(springs_solved_);
    mark_spring_rows(springs_);
    for (int row : spring_rows_) spring_row_marked_[row] = 0;
    // The last revision a step may make is solved whole: the step ends at a solve.
    const bool settle = settles && rev + 1 < cfg_.max_contact_revisions;
    const int rows = static_cast<int>(spring_rows_.size());
    const SolveStatus st = settle ? solver_->settle_changed(A_, spring_rows_.data(), rows, rhs_.data(), dv_.data())
                                  : solver_->solve_changed(A_, spring_rows_.data(), rows, rhs_.data(), dv_.data());
    events_.contact_settles += settle;
    if (!account_resolve(st, t3, same)) return false;
    unconfirmed = settle;
    // A settle is taken whole (the line search's quadratic holds for a whole solve only).
    cut = !settle && rev >= kPlainRevisions && rev + 1 < cfg_.max_contact_revisions && line_search_contacts(s, h);
    candidate_state(s, h);
  }
  if (unconfirmed && !confirm_settled(s, h, same)) return false;
  if (cut) {
    dv_ = dv_full_;
    candidate_state(s, h);
  }
  return true;
}

// The whole solve after settled revisions: from the settled dv_, every row of the cloth, with
// the matrix of the last settle (its rows are reloaded); the contacts are then asked on it.
bool Integrator::confirm_settled(const ClothState& s, double h, bool& same) {
  ++events_.contact_confirmations;
  dv_from_ = dv_;
  const auto t = Clock::now();
  if (!account_resolve(solver_->resolve(A_, rhs_.data(), dv_.data()), t, same)) return false;
  candidate_state(s, h);
  return true;
}

// A re-solve's accounting (begun at t0, from dv_from_): its iterations and time, whether it
// left dv_ as it was (`same`: whatever the solver; a PCG guess already within its tolerance),
// and dv_full_; false if it failed (resolved()).
bool Integrator::account_resolve(SolveStatus st, Clock::time_point t0, bool& same) {
  solver_synced_ = st == SolveStatus::Ok;
  timing_.iterations += solver_->iterations();
  same = dv_ == dv_from_;
  timing_.solve_ms += ms_since(t0);
  if (!resolved(st)) return false;
  dv_full_ = dv_;
  return true;
}

// False, with the cause counted and the warm start cleared, if a solve failed or left dv_ not
// finite.
bool Integrator::resolved(SolveStatus st) {
  if (st == SolveStatus::Ok && dv_.allFinite()) return true;
  switch (st) {
    case SolveStatus::Ok: ++events_.non_finite; break;
    case SolveStatus::NotConverged: ++events_.solver_not_converged; break;
    case SolveStatus::NotPositiveDefinite: ++events_.not_positive_definite; break;
    default: ++events_.solver_error; break;
  }
  dv_.setZero();
  dv_prev_.setZero();
  return false;
}

// Depth along its normal of a one-sided spring's point at the end of the step dv (alpha 1: the
// point moves h (v + dv), the proxy h dv_p), m.
double Integrator::spring_depth(const PointSpring& sp, const ClothState& s, double h,
                                const Eigen::VectorXd& dv) const {
  const auto& e = model_.elements[sp.tri];
  Vec3 r = -h * dv.segment<3>(3 * (sys_.free_nodes + sp.proxy));
  for (int k = 0; k < 3; ++k) {
    const int fk = model_.free_index[e.v[k]];
    r += sp.b[k] * h * (fk < 0 ? s.v[e.v[k]] : Vec3(s.v[e.v[k]] + dv.segment<3>(3 * fk)));
  }
  return sp.depth0 - sp.n.dot(r);
}

// The active set as a globalized semismooth Newton method. With backward Euler (alpha 1) the
// step minimizes the incremental potential Phi: the quadratic of eq. 9 with every contact's
// penalty one-sided, 1/2 kn max(0, depth)^2 (convex). A re-solve minimizes the quadratic that
// takes the new set's contacts as two-sided; taken whole, it can overshoot: an impact's
// contacts push the cloth clear, all are released, the cloth falls back in, all are added...
// (the random two-finger runs of `hapticloth-bench stability` cycled so until the revision cap,
// and the set frozen there left contacts pulling the cloth 0.47 mm into the fingertip). So
// the step goes from the point the set was decided at (dv_from_) towards the re-solve (dv_)
// only as far as Phi decreases: the root of dPhi/dt on [0, 1], piecewise linear and
// non-decreasing in t. The quadratic part is (t - 1) delta^T A delta (the re-solve's gradient
// is zero at t = 1); a contact of the new set adds -kn min(0, depth) dd (its linear spring
// pulls where the one-sided one does not); a released contact kn max(0, depth) dd.
// Friction is held as the new set has it. At alpha < 1 the quadratic is not Phi, and the re-solve
// is taken whole; so is it when no spring is one-sided (a contact owner may leave kn 0: the
// fingertips do in the multirate path's long steps). Returns true if the step was cut short of
// the re-solve.
bool Integrator::line_search_contacts(const ClothState& s, double h) {
  const auto one_sided = [](const PointSpring& sp) { return sp.kn > 0.0; };
  if (alpha_ != 1.0 || (std::none_of(springs_.begin(), springs_.end(), one_sided) &&
                        std::none_of(springs_solved_.begin(), springs_solved_.end(), one_sided)))
    return false;
  // The contacts released by this step's re-solves so far (springs_solved_ less springs_,
  // added to those released before) stay in Phi: a re-solve without them must not push their
  // points back inside unseen, only to add them again two re-solves later.
  auto before = [](const PointSpring& a, const PointSpring& b) {
    return a.proxy < b.proxy || (a.proxy == b.proxy && a.key < b.key);
  };
  auto in_set = [&](const PointSpring& sp) {
    return std::binary_search(springs_.begin(), springs_.end(), sp, before);
  };
  for (const PointSpring& sp : springs_solved_)
    if (sp.kn > 0.0 && !in_set(sp)) released_.push_back(sp);
  std::sort(released_.begin(), released_.end(), before);
  released_.erase(std::unique(released_.begin(), released_.end(),
                              [](const PointSpring& a, const PointSpring& b) { return a.proxy == b.proxy && a.key == b.key; }),
                  released_.end());
  released_.erase(std::remove_if(released_.begin(), released_.end(), in_set), released_.end());
  ls_terms_.clear();
  auto add_term = [&](const PointSpring& sp, bool in) {
    const double d0 = spring_depth(sp, s, h, dv_from_), d1 = spring_depth(sp, s, h, dv_);
    ls_terms_.push_back({sp.kn, d0, d1 - d0, in});
  };
  for (const PointSpring& sp : springs_)
    if (sp.kn > 0.0) add_term(sp, true);
  for (const PointSpring& sp : released_) add_term(sp, false);
  auto contacts_slope = [&](double t) {
    double g = 0.0;
    for (const DepthTerm& c : ls_terms_) {
      const double d = c.d + t * c.dd;
      g += c.in_set ? -c.kn * std::min(0.0, d) * c.dd : c.kn * std::max(0.0, d) * c.dd;
    }
    return g;
  };
  // At t = 1 the quadratic part is zero: most re-solves are taken whole without the product.
  if (contacts_slope(1.0) <= 0.0) return false;
  delta_ = dv_ - dv_from_;
  A_.multiply(delta_.data(), a_delta_.data());
  const double dad = delta_.dot(a_delta_);
  if (!(dad > 0.0)) return false;
  auto slope = [&](double t) { return (t - 1.0) * dad + contacts_slope(t); };
  if (slope(0.0) >= 0.0) return false;  // no descent along it: the whole step
  double lo = 0.0, hi = 1.0;
  for (int it = 0; it < 30; ++it) {
    const double mid = 0.5 * (lo + hi);
    (slope(mid) < 0.0 ? lo : hi) = mid;
  }
  ++events_.contact_line_cuts;
  dv_ = dv_from_ + hi * delta_;
  return true;
}

// Energy explosion: the step created far more energy than the external forces supplied (their
// work over the step goes to `work`). The elastic energy is >= 0 (Psi >= 0 for laws through the
// origin), so kinetic + gravitational energy is a lower bound of the new total and no second
// pass over the elements is needed: a blow-up always shows in the velocities. Counted.
bool Integrator::energy_explosion(const ClothState& s, double& work) {
  double ke = 0.0, eg = 0.0;
  work = 0.0;
  for (int i = 0; i < model_.num_vertices(); ++i) {
    if (model_.free_index[i] < 0) continue;
    ke += 0.5 * model_.mass[i] * vn_[i].squaredNorm();
    eg -= model_.mass[i] * cfg_.gravity.dot(xn_[i]);
    work += f_ext_[i].dot(xn_[i] - s.x[i]);
  }
  work += contact_work(s);
  const double e_new_lower = ke + eg;
  if (!std::isfinite(e_new_lower)) {
    ++events_.non_finite;
    return true;
  }
  const double gain = e_new_lower - energy_old_ - work;
  if (gain > cfg_.explosion_ratio * energy_scale_) {
    ++events_.energy_explosions;
    return true;
  }
  return false;
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
