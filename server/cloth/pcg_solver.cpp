// The PCG solver's driver (pcg_solver.hpp): analysis, the solves and re-solves with the float
// copy's fallback to double, loading the block copy, and block-Jacobi's iteration.
#include "cloth/pcg_solver.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <string>
#include <thread>
#include <stdexcept>
#include <vector>

namespace hapticloth::cloth::pcg {

PcgSolver::PcgSolver(const PcgOptions& o)
      : opt_(o), ssor_(o.preconditioner == PcgPreconditioner::Ssor), omega_(o.ssor_omega) {
  if (!(o.tolerance > 0.0) || !std::isfinite(o.tolerance) || o.max_iterations < 1)
    throw std::invalid_argument("pcg: tolerance must be > 0 and max_iterations >= 1");
  if (!(o.ssor_omega >= 1.0 && o.ssor_omega < 2.0))
    throw std::invalid_argument("pcg: ssor_omega must be in [1, 2)");
}

void PcgSolver::analyze(const SymCsr& A) {
  if (A.n % 3 != 0) throw std::invalid_argument("pcg: matrix size must be a multiple of 3");
  if (!A.block3) throw std::invalid_argument("pcg: the matrix must have 3x3 block structure");
  n_ = A.n;
  precision_fallbacks_ = 0;
  helper_sweeps_ = 0;
  // One padding entry: the vectorized product reads and writes 4 lanes per block row.
  r_.assign(n_ + 1, 0.0);
  z_.assign(n_ + 1, 0.0);
  p_.assign(n_ + 1, 0.0);
  q_.assign(n_ + 1, 0.0);
  x0_.assign(n_ + 1, 0.0);
  guess_.assign(n_, 0.0);
  inv_.assign(9 * (n_ / 3), 0.0);
  // Hub rows: block rows far longer than a mesh's (the fingertip proxies, coupled to every
  // vertex), found as CHOLMOD's ordering finds them. The matrix copy keeps them apart; the
  // preconditioner's dense block takes them when asked (hub_block).
  const int nb = n_ / 3;
  const double dense = std::max(16.0, 10.0 * std::sqrt(static_cast<double>(n_)));
  std::vector<int> hub_rows;
  for (int br = 0; br < nb; ++br)
    if (A.rowptr[3 * br + 1] - A.rowptr[3 * br] > dense) hub_rows.push_back(br);
  // SSOR keeps every hub in the cluster (a hub row has no block of its own in the sweeps).
  if (ssor_ && static_cast<int>(hub_rows.size()) > kMaxCluster)
    throw std::invalid_argument("pcg: SSOR takes at most " + std::to_string(kMaxCluster) + " hub rows, not " +
                                std::to_string(hub_rows.size()) + " (use block-jacobi)");
  sweep_order(A, hub_rows);
  matrix_float_.with_dinv = matrix_double_.with_dinv = ssor_;
  matrix_float_.dinv_scale = matrix_double_.dinv_scale = omega_;
  if (opt_.single_precision_matrix) matrix_float_.build_pattern(A, hub_rows, rank_);
  matrix_double_.build_pattern(A, hub_rows, rank_);  // also the fallback of the float copy
  // SSOR orders the hubs last as one block, whether or not the contact nodes join them.
  hubs_ = opt_.hub_block || ssor_ ? hub_rows : std::vector<int>{};
  local_.assign(nb, -1);
  kind_.assign(nb, kPlain);
  w_.assign(n_ + 1, 0.0);  // padded as the others: the sweeps read 4 lanes
  t_.assign(n_ + 1, 0.0);
  u_.assign(n_ + 1, 0.0);
  at_.assign(n_ + 1, 0.0);
  touched_.clear();
  touched_.reserve(nb);
  listed_.assign(nb, 0);
  sorted_.clear();
  sorted_.reserve(nb);
  cluster_.clear();
  cluster_.reserve(kMaxCluster);
  weight_.clear();
  weight_.reserve((hub_rows.size() + 1) * static_cast<size_t>(nb));  // a hub row reaches every node at most
}

// With the float copy, a system too ill-conditioned for its rounding (the residual stalls
// above the tolerance: a 1000x stiffer cloth at a 20 ms step in hapticloth-bench stability)
// is solved again with the double copy (its iterations are the ones reported).
SolveStatus PcgSolver::solve(const SymCsr& A, const double* b, double* x) {
  float_in_use_ = opt_.single_precision_matrix;
  return with_fallback(A, b, x, [&](auto& M) { return run(M, A, b, x, true); });
}

// The matrix copy and the preconditioner of the last solve serve again.
SolveStatus PcgSolver::resolve(const SymCsr& A, const double* b, double* x) {
  if (!prepared_) return solve(A, b, x);
  return with_fallback(A, b, x, [&](auto& M) { return run(M, A, b, x, false); });
}

// The copy in use (the one the last solve prepared) gets the changed rows.
SolveStatus PcgSolver::solve_changed(const SymCsr& A, const int* block_rows, int count, const double* b,
                            double* x) {
  if (!prepared_) return solve(A, b, x);
  return with_fallback(A, b, x, [&](auto& M) { return run_changed(M, A, block_rows, count, b, x); });
}

// The changed rows reloaded as for a re-solve, then the cluster settled (settle_cluster) and
// no iteration. Before any solve it is a whole solve.
SolveStatus PcgSolver::settle_changed(const SymCsr& A, const int* block_rows, int count, const double* b,
                             double* x) {
  if (!prepared_) return solve(A, b, x);
  return with_fallback(A, b, x, [&](auto& M) { return settle(M, A, block_rows, count, b, x); });
}

template <class T>
SolveStatus PcgSolver::run(Bsr<T>& M, const SymCsr& A, const double* b, double* x, bool load) {
  iterations_ = 0;
  residual_ = 0.0;
  if (load && !prepare(M, A)) return SolveStatus::NotPositiveDefinite;
  return iterate_preconditioned(M, b, x);
}

// A re-solve after a change in a few block rows: those rows reloaded and re-preconditioned,
// the hubs' blocks reloaded and their dense block factored again. A contact revision then
// reloads the rows of the vertices in contact and the hubs, not the whole matrix.
template <class T>
SolveStatus PcgSolver::run_changed(Bsr<T>& M, const SymCsr& A, const int* rows, int count, const double* b,
                          double* x) {
  if (!reload_changed(M, A, rows, count)) return SolveStatus::NotPositiveDefinite;
  return iterate_preconditioned(M, b, x);
}

// The listed rows reloaded and re-preconditioned, the hubs' blocks reloaded and the cluster
// factored again; false if a block is not positive definite.
template <class T>
bool PcgSolver::reload_changed(Bsr<T>& M, const SymCsr& A, const int* rows, int count) {
  iterations_ = 0;
  residual_ = 0.0;
  prepared_ = false;
  // The listed rows in two halves and the hubs' blocks, on the pool's two threads when there
  // is one (rows apart write apart, and the hubs' lists are apart from the rows): a kept
  // matrix's step can list some hundreds of rows.
  std::array<char, 2> ok{};
  auto piece = [&](int c) {
    if (c == 2) {
      reload_hubs(M, A, rows, count);
      return;
    }
    bool pd = true;
    for (int i = count * c / 2; i < count * (c + 1) / 2; ++i) {
      pd = M.load_row(A, rows[i]) && pd;
      if (!ssor_) pd = invert_diagonal(A, rows[i], M.diag[rows[i]]) && pd;
    }
    ok[c] = pd;
  };
  in_parallel(3, piece);
  if (!ok[0] || !ok[1]) return false;
  if (!hubs_.empty() && !factor_cluster(M, A)) return false;
  prepared_ = true;
  return true;
}

// The preconditioner's PCG from the guess in x.
template <class T>
SolveStatus PcgSolver::iterate_preconditioned(const Bsr<T>& M, const double* b, double* x) {
  return ssor_ ? iterate_ssor(M, b, x, n_, n_ / 3) : iterate(M, b, x, n_, n_ / 3);
}

// settle_changed's solve: the changed rows reloaded, then the cluster alone, no iteration
// (residual() is left at 0: the rest of the rows are not looked at). Without a cluster, the
// whole solve.
template <class T>
SolveStatus PcgSolver::settle(Bsr<T>& M, const SymCsr& A, const int* rows, int count, const double* b, double* x) {
  if (!reload_changed(M, A, rows, count)) return SolveStatus::NotPositiveDefinite;
  if (cluster_.empty()) return iterate_preconditioned(M, b, x);
  double bn2 = 0.0;
  if (const auto settled = start(b, x, n_, bn2)) return *settled;
  settle_cluster(M, b, x, goal_squared(bn2));
  return SolveStatus::Ok;
}

// The hub rows' blocks after a change in `rows` (Bsr::reload_hubs, which wants them sorted).
template <class T>
void PcgSolver::reload_hubs(Bsr<T>& M, const SymCsr& A, const int* rows, int count) {
  sorted_.assign(rows, rows + count);
  std::sort(sorted_.begin(), sorted_.end());
  sorted_.erase(std::unique(sorted_.begin(), sorted_.end()), sorted_.end());
  for (int r : sorted_) listed_[r] = 1;
  M.reload_hubs(A, sorted_.data(), static_cast<int>(sorted_.size()), listed_);
  for (int r : sorted_) listed_[r] = 0;
}

// The matrix copy, the block-Jacobi inverses and the hub block. False if a diagonal block or
// the hub block is not positive definite.
template <class T>
bool PcgSolver::prepare(Bsr<T>& M, const SymCsr& A) {
  prepared_ = false;
  const int nb = n_ / 3;
  if (!load(M, A)) return false;
  for (int br = 0; br < nb && !ssor_; ++br)
    if (!invert_diagonal(A, br, M.diag[br])) return false;
  if (!hubs_.empty() && !factor_cluster(M, A)) return false;
  prepared_ = true;
  return true;
}

// The matrix copy, in kLoadChunks pieces of rows that the pool's two threads take in turn (a
// late helper leaves the caller more of them), and the hub rows' blocks as one more piece,
// the helper's first (a scan of the hubs' whole rows, which reach every node). False if a
// diagonal block is not positive definite.
template <class T>
bool PcgSolver::load(Bsr<T>& M, const SymCsr& A) {
  const int nb = n_ / 3;
  std::array<char, kLoadChunks> ok{};
  auto chunk = [&](int c) {
    if (c == kLoadChunks) {
      M.load_hubs(A);  // writes the hub arrays only; the rows' pieces skip the hub rows
      return;
    }
    ok[c] = M.load_rows(A, nb * c / kLoadChunks, nb * (c + 1) / kLoadChunks);
  };
  in_parallel(kLoadChunks + 1, chunk);
  return std::all_of(ok.begin(), ok.end(), [](char c) { return c != 0; });
}

// Block-Jacobi's preconditioner: the inverse of block row br's 3x3 diagonal block (at column
// position d of A's row, from the double values). False if it is not positive definite.
// (SSOR's are the matrix copy's own: Bsr::dinv.)
bool PcgSolver::invert_diagonal(const SymCsr& A, int br, int d) {
  const int o = A.rowptr[3 * br], len = A.rowptr[3 * br + 1] - o;
  const double* r0 = A.val.data() + o + d;
  double a[3][3], m[3][3];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) a[r][c] = r0[r * len + c];
  if (!inverse3(a, m)) return false;
  std::copy(&m[0][0], &m[0][0] + 9, inv_.data() + 9 * br);
  return true;
}

// The squared residual that ends the solve: tolerance x the larger of |b| and the residual
// scale (LinearSolver::set_residual_scale), squared.
double PcgSolver::goal_squared(double bn2) const {
  return opt_.tolerance * opt_.tolerance * std::max(bn2, residual_scale_ * residual_scale_);
}

// |b|^2 into bn2 and a finite guess in x (else 0); a status if that settles the solve (b = 0
// or not finite).
std::optional<SolveStatus> PcgSolver::start(const double* b, double* x, int n, double& bn2) {
  bn2 = 0.0;
  for (int i = 0; i < n; ++i) bn2 += b[i] * b[i];
  if (!std::isfinite(bn2)) return SolveStatus::NumericalError;
  if (bn2 == 0.0) {
    std::fill(x, x + n, 0.0);
    return SolveStatus::Ok;
  }
  bool finite = true;
  for (int i = 0; i < n; ++i) finite = finite && std::isfinite(x[i]);
  if (!finite) std::fill(x, x + n, 0.0);
  return std::nullopt;
}

// Preconditioned conjugate gradients from the guess in x, until |r| <= tolerance |b|.
template <class T>
SolveStatus PcgSolver::iterate(const Bsr<T>& M, const double* b, double* x, int n, int nb) {
  double bn2 = 0.0;
  if (const auto settled = start(b, x, n, bn2)) return *settled;
  const double bnorm = std::sqrt(bn2);
  const double goal2 = goal_squared(bn2);
  settle_cluster(M, b, x, goal2);
  double* r = r_.data();
  double* z = z_.data();
  double* p = p_.data();
  double* q = q_.data();
  std::copy(x, x + n, x0_.data());  // padded copy of the guess for the product
  M.multiply_dot(x0_.data(), q);
  for (int i = 0; i < n; ++i) r[i] = b[i] - q[i];
  double rr;
  double rz = precondition(r, z, nb, rr);
  if (rr <= goal2) {
    residual_ = std::sqrt(rr) / bnorm;
    return SolveStatus::Ok;
  }
  std::copy(z, z + n, p);
  for (int it = 1; it <= opt_.max_iterations; ++it) {
    const double pq = M.multiply_dot(p, q);
    iterations_ = it;
    if (!(pq > 0.0)) return std::isfinite(pq) ? SolveStatus::NotPositiveDefinite : SolveStatus::NumericalError;
    const double alpha = rz / pq;
    for (int i = 0; i < n; ++i) {
      x[i] += alpha * p[i];
      r[i] -= alpha * q[i];
    }
    const double rz_new = precondition(r, z, nb, rr);
    if (!std::isfinite(rr)) return SolveStatus::NumericalError;
    if (rr <= goal2) {
      residual_ = std::sqrt(rr) / bnorm;
      return SolveStatus::Ok;
    }
    const double beta = rz_new / rz;
    for (int i = 0; i < n; ++i) p[i] = z[i] + beta * p[i];
    rz = rz_new;
  }
  residual_ = std::sqrt(rr) / bnorm;
  return SolveStatus::NotConverged;
}

// z = M^-1 r, returning r . z, with r . r in `rr`, in one pass. M is block-Jacobi (the 3x3
// diagonal blocks' inverses) except on the cluster of hub rows and the nodes they touch, which
// is one dense block (factor_cluster).
double PcgSolver::precondition(const double* r, double* z, int nb, double& rr) {
  double rz = 0.0;
  rr = 0.0;
  if (!cluster_.empty()) {
    const int m = 3 * static_cast<int>(cluster_.size());
    for (size_t a = 0; a < cluster_.size(); ++a)
      for (int c = 0; c < 3; ++c) cz_[3 * a + c] = r[3 * cluster_[a] + c];
    cholesky_solve(dense_.data(), m, cz_.data());
    for (size_t a = 0; a < cluster_.size(); ++a)
      for (int c = 0; c < 3; ++c) {
        const int i = 3 * cluster_[a] + c;
        z[i] = cz_[3 * a + c];
        rz += r[i] * z[i];
        rr += r[i] * r[i];
      }
  }
  for (int br = 0; br < nb; ++br) {
    if (local_[br] >= 0) continue;
    const double* m = inv_.data() + 9 * br;
    const double r0 = r[3 * br], r1 = r[3 * br + 1], r2 = r[3 * br + 2];
    const double z0 = m[0] * r0 + m[1] * r1 + m[2] * r2;
    const double z1 = m[3] * r0 + m[4] * r1 + m[5] * r2;
    const double z2 = m[6] * r0 + m[7] * r1 + m[8] * r2;
    z[3 * br] = z0;
    z[3 * br + 1] = z1;
    z[3 * br + 2] = z2;
    rz += r0 * z0 + r1 * z1 + r2 * z2;
    rr += r0 * r0 + r1 * r1 + r2 * r2;
  }
  return rz;
}

// r = b - A x, returning r . r.
template <class T>
double PcgSolver::true_residual(const Bsr<T>& M, const double* b, const double* x, double* r, int n) {
  std::copy(x, x + n, x0_.data());  // padded for the product
  M.multiply_dot(x0_.data(), at_.data());
  V4 rr{};
  int i = 0;
  for (; i + 4 <= n; i += 4) {
    const V4 ri = load4(b + i) - load4(at_.data() + i);
    std::memcpy(r + i, &ri, sizeof ri);
    rr += ri * ri;
  }
  double s = rr[0] + rr[1] + rr[2] + rr[3];
  for (; i < n; ++i) {
    r[i] = b[i] - at_[i];
    s += r[i] * r[i];
  }
  return s;
}

// x += alpha t, r -= alpha A t, r' -= alpha (t + u) (= A' p'), then z' = E r': block rows
// [0, split_) and [split_, nb) at once, in 4-lane runs of entries (with the parts split by
// number, each range on the thread whose part it holds, its data in that core's cache); the
// cluster's z' after. Returns r . r, and r' . z' in rz.
template <class T>
double PcgSolver::update(const Bsr<T>& M, double alpha, double* x, double* r, double* rb, double* zb, double& rz) {
  const int nb = n_ / 3;
  auto half = [&](int q) {
    const int lo = q == 0 ? 0 : split_, hi = q == 0 ? split_ : nb;
    part_sum_[q] = update_range(alpha, x, r, rb, 3 * lo, 3 * hi);
    part_rz_[q] = multiply_d(M, rb, zb, lo, hi);
  };
  in_parallel(2, half);
  rz = part_rz_[0] + part_rz_[1] + multiply_cluster_d(rb, zb);
  return part_sum_[0] + part_sum_[1];
}

// update's vector part on the entries [i0, i1) (i0 a multiple of 4), returning their r . r.
double PcgSolver::update_range(double alpha, double* x, double* r, double* rb, int i0, int i1) const {
  const double* t = t_.data();
  const double* u = u_.data();
  const double* at = at_.data();
  const V4 a = splat(alpha);
  V4 rr{};
  int i = i0;
  for (; i + 4 <= i1; i += 4) {
    const V4 xi = load4(x + i) + a * load4(t + i);
    const V4 ri = load4(r + i) - a * load4(at + i);
    const V4 bi = load4(rb + i) - a * (load4(t + i) + load4(u + i));
    std::memcpy(x + i, &xi, sizeof xi);
    std::memcpy(r + i, &ri, sizeof ri);
    std::memcpy(rb + i, &bi, sizeof bi);
    rr += ri * ri;
  }
  double sum = rr[0] + rr[1] + rr[2] + rr[3];
  for (; i < i1; ++i) {
    x[i] += alpha * t[i];
    r[i] -= alpha * at[i];
    rb[i] -= alpha * (t[i] + u[i]);
    sum += r[i] * r[i];
  }
  return sum;
}

// z = E r (the 3x3 diagonal blocks over omega) on block rows [lo, hi) outside the cluster,
// returning their r . z.
template <class T>
double PcgSolver::multiply_d(const Bsr<T>& M, const double* r, double* z, int lo, int hi) const {
  constexpr int K = Bsr<T>::kBlock;
  const T* val = M.val.data();
  const int* dblk = M.dblk.data();
  const signed char* kind = kind_.data();
  const V4 scale = splat(1.0 / omega_);
  V4 dot{};
  for (int br = lo; br < hi; ++br) {
    if (kind[br] == kCluster) continue;
    const V4 zi = scale * block_times(val + K * dblk[br], r + 3 * br);  // lane 3 is 0
    store3(z + 3 * br, zi);
    dot += load3(r + 3 * br) * zi;  // the next row's r may be the other thread's
  }
  return sum3(dot);
}

// The float and double copies' instantiations, for the other files of the solver.
template SolveStatus PcgSolver::run<float>(Bsr<float>& M, const SymCsr& A, const double* b, double* x, bool load);
template SolveStatus PcgSolver::run<double>(Bsr<double>& M, const SymCsr& A, const double* b, double* x, bool load);
template SolveStatus PcgSolver::run_changed<float>(Bsr<float>& M, const SymCsr& A, const int* rows, int count, const double* b,
                          double* x);
template SolveStatus PcgSolver::run_changed<double>(Bsr<double>& M, const SymCsr& A, const int* rows, int count, const double* b,
                          double* x);
template bool PcgSolver::reload_changed<float>(Bsr<float>& M, const SymCsr& A, const int* rows, int count);
template bool PcgSolver::reload_changed<double>(Bsr<double>& M, const SymCsr& A, const int* rows, int count);
template SolveStatus PcgSolver::iterate_preconditioned<float>(const Bsr<float>& M, const double* b, double* x);
template SolveStatus PcgSolver::iterate_preconditioned<double>(const Bsr<double>& M, const double* b, double* x);
template SolveStatus PcgSolver::settle<float>(Bsr<float>& M, const SymCsr& A, const int* rows, int count, const double* b, double* x);
template SolveStatus PcgSolver::settle<double>(Bsr<double>& M, const SymCsr& A, const int* rows, int count, const double* b, double* x);
template void PcgSolver::reload_hubs<float>(Bsr<float>& M, const SymCsr& A, const int* rows, int count);
template void PcgSolver::reload_hubs<double>(Bsr<double>& M, const SymCsr& A, const int* rows, int count);
template bool PcgSolver::prepare<float>(Bsr<float>& M, const SymCsr& A);
template bool PcgSolver::prepare<double>(Bsr<double>& M, const SymCsr& A);
template bool PcgSolver::load<float>(Bsr<float>& M, const SymCsr& A);
template bool PcgSolver::load<double>(Bsr<double>& M, const SymCsr& A);
template SolveStatus PcgSolver::iterate<float>(const Bsr<float>& M, const double* b, double* x, int n, int nb);
template SolveStatus PcgSolver::iterate<double>(const Bsr<double>& M, const double* b, double* x, int n, int nb);
template double PcgSolver::true_residual<float>(const Bsr<float>& M, const double* b, const double* x, double* r, int n);
template double PcgSolver::true_residual<double>(const Bsr<double>& M, const double* b, const double* x, double* r, int n);
template double PcgSolver::update<float>(const Bsr<float>& M, double alpha, double* x, double* r, double* rb, double* zb, double& rz);
template double PcgSolver::update<double>(const Bsr<double>& M, double alpha, double* x, double* r, double* rb, double* zb, double& rz);
template double PcgSolver::multiply_d<float>(const Bsr<float>& M, const double* r, double* z, int lo, int hi) const;
template double PcgSolver::multiply_d<double>(const Bsr<double>& M, const double* r, double* z, int lo, int hi) const;

}  // namespace hapticloth::cloth::pcg

namespace hapticloth::cloth {

std::unique_ptr<LinearSolver> make_pcg_solver(const PcgOptions& opt) {
  return std::make_unique<pcg::PcgSolver>(opt);
}

}  // namespace hapticloth::cloth
