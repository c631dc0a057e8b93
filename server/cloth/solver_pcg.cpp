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

#include "cloth/pcg_blocks.hpp"
#include "cloth/solver.hpp"
#include "cloth/worker_pool.hpp"

namespace hapticloth::cloth {

const char* to_string(SolveStatus s) {
  switch (s) {
    case SolveStatus::Ok: return "ok";
    case SolveStatus::NotConverged: return "not_converged";
    case SolveStatus::NotPositiveDefinite: return "not_positive_definite";
    case SolveStatus::NumericalError: return "numerical_error";
  }
  return "?";
}

const char* to_string(PcgPreconditioner p) {
  return p == PcgPreconditioner::Ssor ? "ssor" : "block-jacobi";
}

namespace {

using namespace pcg;

class PcgSolver final : public LinearSolver {
 public:
  explicit PcgSolver(const PcgOptions& o)
      : opt_(o), ssor_(o.preconditioner == PcgPreconditioner::Ssor), omega_(o.ssor_omega) {
    if (!(o.tolerance > 0.0) || !std::isfinite(o.tolerance) || o.max_iterations < 1)
      throw std::invalid_argument("pcg: tolerance must be > 0 and max_iterations >= 1");
    if (!(o.ssor_omega >= 1.0 && o.ssor_omega < 2.0))
      throw std::invalid_argument("pcg: ssor_omega must be in [1, 2)");
  }
  const char* name() const override { return "pcg"; }
  void use_pool(WorkerPool* pool) override { pool_ = pool; }

  void analyze(const SymCsr& A) override {
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
  SolveStatus solve(const SymCsr& A, const double* b, double* x) override {
    float_in_use_ = opt_.single_precision_matrix;
    return with_fallback(A, b, x, [&](auto& M) { return run(M, A, b, x, true); });
  }
  // The matrix copy and the preconditioner of the last solve serve again.
  SolveStatus resolve(const SymCsr& A, const double* b, double* x) override {
    if (!prepared_) return solve(A, b, x);
    return with_fallback(A, b, x, [&](auto& M) { return run(M, A, b, x, false); });
  }
  // The copy in use (the one the last solve prepared) gets the changed rows.
  SolveStatus solve_changed(const SymCsr& A, const int* block_rows, int count, const double* b,
                            double* x) override {
    if (!prepared_) return solve(A, b, x);
    return with_fallback(A, b, x, [&](auto& M) { return run_changed(M, A, block_rows, count, b, x); });
  }
  // The changed rows reloaded as for a re-solve, then the cluster settled (settle_cluster) and
  // no iteration. Before any solve it is a whole solve.
  SolveStatus settle_changed(const SymCsr& A, const int* block_rows, int count, const double* b,
                             double* x) override {
    if (!prepared_) return solve(A, b, x);
    return with_fallback(A, b, x, [&](auto& M) { return settle(M, A, block_rows, count, b, x); });
  }
  // Only with a dense block to settle: the hub rows (SSOR keeps them always; block-Jacobi with
  // hub_block).
  bool settles_locally() const override { return !hubs_.empty(); }

 private:
  // f(copy) on the copy in use; a float copy that stalls above the tolerance hands the system
  // to a whole double solve from the same guess.
  template <class F>
  SolveStatus with_fallback(const SymCsr& A, const double* b, double* x, F&& f) {
    if (!float_in_use_) return f(matrix_double_);
    std::copy(x, x + n_, guess_.begin());
    const SolveStatus st = f(matrix_float_);
    if (st != SolveStatus::NotConverged) return st;
    float_in_use_ = false;
    ++precision_fallbacks_;
    std::copy(guess_.begin(), guess_.begin() + n_, x);
    return run(matrix_double_, A, b, x, true);
  }

  template <class T>
  SolveStatus run(Bsr<T>& M, const SymCsr& A, const double* b, double* x, bool load) {
    iterations_ = 0;
    residual_ = 0.0;
    if (load && !prepare(M, A)) return SolveStatus::NotPositiveDefinite;
    return iterate_preconditioned(M, b, x);
  }

  // A re-solve after a change in a few block rows: those rows reloaded and re-preconditioned,
  // the hubs' blocks reloaded and their dense block factored again. A contact revision of the
  // pinched 968-triangle square then reloads some tens of rows of the matrix, not all of it.
  template <class T>
  SolveStatus run_changed(Bsr<T>& M, const SymCsr& A, const int* rows, int count, const double* b,
                          double* x) {
    if (!reload_changed(M, A, rows, count)) return SolveStatus::NotPositiveDefinite;
    return iterate_preconditioned(M, b, x);
  }

  // The listed rows reloaded and re-preconditioned, the hubs' blocks reloaded and the cluster
  // factored again; false if a block is not positive definite.
  template <class T>
  bool reload_changed(Bsr<T>& M, const SymCsr& A, const int* rows, int count) {
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
  SolveStatus iterate_preconditioned(const Bsr<T>& M, const double* b, double* x) {
    return ssor_ ? iterate_ssor(M, b, x, n_, n_ / 3) : iterate(M, b, x, n_, n_ / 3);
  }

  // settle_changed's solve: the changed rows reloaded, then the cluster alone, no iteration
  // (residual() is left at 0: the rest of the rows are not looked at). Without a cluster, the
  // whole solve.
  template <class T>
  SolveStatus settle(Bsr<T>& M, const SymCsr& A, const int* rows, int count, const double* b, double* x) {
    if (!reload_changed(M, A, rows, count)) return SolveStatus::NotPositiveDefinite;
    if (cluster_.empty()) return iterate_preconditioned(M, b, x);
    double bn2 = 0.0;
    if (const auto settled = start(b, x, n_, bn2)) return *settled;
    settle_cluster(M, b, x, goal_squared(bn2));
    return SolveStatus::Ok;
  }

  // The hub rows' blocks after a change in `rows` (Bsr::reload_hubs, which wants them sorted).
  template <class T>
  void reload_hubs(Bsr<T>& M, const SymCsr& A, const int* rows, int count) {
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
  bool prepare(Bsr<T>& M, const SymCsr& A) {
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
  // the helper's first (a scan of the hubs' whole rows: 14 us a step on the pinched
  // 4050-triangle square). False if a diagonal block is not positive definite.
  template <class T>
  bool load(Bsr<T>& M, const SymCsr& A) {
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

  // f(i) for i in [0, n): on the pool's two threads when there is one.
  template <class F>
  void in_parallel(int n, F& f) {
    if (pool_) {
      pool_->run(n, f);
      return;
    }
    for (int i = 0; i < n; ++i) f(i);
  }

  // A run of the sweeps' order, order_ [begin, end).
  struct Rows {
    int begin = 0, end = 0;
    int size() const { return end - begin; }
  };
  Rows part(int q) const { return {seg_[q], seg_[q + 1]}; }
  Rows separator() const { return {seg_[2], seg_[3]}; }

  // f(one, two, sums) for the two parts, which share no block, with part q's sums into
  // part_sum_[q]: on the pool, a thread each (f(part q, none)); without one, on this thread in
  // turn (f(part 0, part 1)), so that each sweep advances two independent chains of rows at
  // once (a row waits on the one before it in its own part only). The sums are the same either way.
  template <class F>
  void both_parts(F& f) {
    if (!pool_) {
      double sums[2];
      f(part(0), part(1), sums);
      part_sum_ = {sums[0], sums[1]};
      return;
    }
    const auto caller = std::this_thread::get_id();
    auto one = [&](int q) {
      double sums[2];
      f(part(q), Rows{}, sums);
      part_sum_[q] = sums[0];
      if (std::this_thread::get_id() != caller) ++helper_sweeps_;  // the helper's only write to it
    };
    pool_->run(2, one);
  }

  // f(row, 0) for the rows of `one` and f(row, 1) for those of `two`, taking one of each in
  // turn, first to last (kReverse: last to first).
  template <bool kReverse, class F>
  __attribute__((always_inline)) void in_turn(Rows one, Rows two, F&& f) const {
    const int n = std::max(one.size(), two.size());
    for (int k = 0; k < n; ++k) {
      if (k < one.size()) f(order_[kReverse ? one.end - 1 - k : one.begin + k], 0);
      if (k < two.size()) f(order_[kReverse ? two.end - 1 - k : two.begin + k], 1);
    }
  }

  // Block-Jacobi's preconditioner: the inverse of block row br's 3x3 diagonal block (at column
  // position d of A's row, from the double values). False if it is not positive definite.
  // (SSOR's are the matrix copy's own: Bsr::dinv.)
  bool invert_diagonal(const SymCsr& A, int br, int d) {
    const int o = A.rowptr[3 * br], len = A.rowptr[3 * br + 1] - o;
    const double* r0 = A.val.data() + o + d;
    double a[3][3], m[3][3];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) a[r][c] = r0[r * len + c];
    if (!inverse3(a, m)) return false;
    std::copy(&m[0][0], &m[0][0] + 9, inv_.data() + 9 * br);
    return true;
  }


  // Before the iterations, the cluster's rows (the proxies and the vertices they hold, the
  // preconditioner's dense block) solved with the rest of x held: x_C += A_CC^-1 (b - A x)_C,
  // one block Gauss-Seidel step. When contacts change, nearly all of the residual is there
  // (97.5-100% of |r|^2 at the start of the 4050-triangle script's release solves: a proxy is
  // massless, its springs the stiffest terms), and the PCG's first step, one length for every
  // row, takes off a factor of only 3-7 of it. Settled first, the script's stroke took 34% fewer
  // iterations (docs/performance.md, "The proxies' rows settled first"). Left as it is when
  // those rows are already within the goal, so that a solved guess stays exactly as it was
  // (the integrator's same-candidate test, Integrator::revise_contacts).
  template <class T>
  void settle_cluster(const Bsr<T>& M, const double* b, double* x, double goal2) {
    if (cluster_.empty()) return;
    const int m = 3 * static_cast<int>(cluster_.size());
    gather_cluster(x, cx_.data());
    cholesky_multiply(dense_.data(), m, cx_.data(), cz_.data(), ctmp_.data());
    for_cluster_blocks(M, [&](int j, const T* B, int a) { add_block(B, x + 3 * j, cz_.data() + 3 * a); });
    double rc2 = 0.0;
    for (size_t a = 0; a < cluster_.size(); ++a)
      for (int c = 0; c < 3; ++c) {
        const int l = 3 * static_cast<int>(a) + c;
        cz_[l] = b[3 * cluster_[a] + c] - cz_[l];
        rc2 += cz_[l] * cz_[l];
      }
    if (rc2 <= goal2) return;
    cholesky_solve(dense_.data(), m, cz_.data());
    for (size_t a = 0; a < cluster_.size(); ++a)
      for (int c = 0; c < 3; ++c) x[3 * cluster_[a] + c] += cz_[3 * static_cast<int>(a) + c];
  }

  // The squared residual that ends the solve: tolerance x the larger of |b| and the residual
  // scale (LinearSolver::set_residual_scale), squared.
  double goal_squared(double bn2) const {
    return opt_.tolerance * opt_.tolerance * std::max(bn2, residual_scale_ * residual_scale_);
  }

  // |b|^2 into bn2 and a finite guess in x (else 0); a status if that settles the solve (b = 0
  // or not finite).
  static std::optional<SolveStatus> start(const double* b, double* x, int n, double& bn2) {
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
  SolveStatus iterate(const Bsr<T>& M, const double* b, double* x, int n, int nb) {
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
  double precondition(const double* r, double* z, int nb, double& rr) {
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

  // Symmetric block Gauss-Seidel (SSOR) by Eisenstat's trick. A = L + D + L^T with D the 3x3
  // diagonal blocks and the cluster's dense block, the cluster ordered last, and E = D / omega
  // (the cluster's block unrelaxed); the preconditioner is M = (E + L) E^-1 (E + L^T), SSOR's
  // up to a factor. CG runs on A' = (E + L)^-1 A (E + L^T)^-1 with the preconditioner E, whose
  // product costs one backward and one forward sweep, each over half the blocks: with t =
  // (E + L^T)^-1 p', A' p' = t + (E + L)^-1 (p' + (D - 2E) t), from A = (E + L) + (E + L^T) +
  // D - 2E. So an iteration reads the matrix once, as block-Jacobi's does, and the cloth's
  // smooth modes converge in fewer (on the pinched 4050-triangle square 23 -> 9 a step). x is
  // carried along (x += alpha t), and so is the true residual r = b - A x (r -= alpha A t, the
  // forward sweep giving A t = L t + p' + (D - E) t), so the solve stops at |r| <= tolerance
  // |b| as block-Jacobi's does. That recursion drifts (A t is a difference of terms up to 1e8
  // times larger with stiff contact springs: 1e-7 relative in test_solver's pinch), so every
  // kRefresh-th sweep also takes r = (E + L) r' = E r' + L r' afresh from the transformed one.
  // An iteration is two passes that the pool's two threads share (sweep_order): the product,
  // and the update with the next z' = E r'.
  template <class T>
  SolveStatus iterate_ssor(const Bsr<T>& M, const double* b, double* x, int n, int nb) {
    double bn2 = 0.0;
    if (const auto settled = start(b, x, n, bn2)) return *settled;
    const double bnorm = std::sqrt(bn2);
    double* r = r_.data();    // b - A x
    double* rb = z_.data();   // r' = (E + L)^-1 r
    double* zb = q_.data();   // z' = E r'
    double* pb = p_.data();   // p'
    const double goal2 = goal_squared(bn2);
    settle_cluster(M, b, x, goal2);
    double rr = residual_and_lower_solve(M, b, x, r, rb);
    if (rr <= goal2) {
      residual_ = std::sqrt(rr) / bnorm;
      return SolveStatus::Ok;
    }
    double rz = multiply_d(M, rb, zb, 0, nb) + multiply_cluster_d(rb, zb);
    std::copy(zb, zb + n, pb);
    double beta = 0.0;  // p' = z' + beta p', taken row by row in the next product
    int checked = 0;    // the iteration whose converged residual was checked
    for (int it = 1; it <= opt_.max_iterations; ++it) {
      const bool refresh = it % kRefresh == 0, turn = it > 1;
      const double pq = refresh ? product<true>(M, turn, beta, pb, zb, rb, r)
                                : product<false>(M, turn, beta, pb, zb, rb, r);
      iterations_ = it;
      if (!(pq > 0.0)) return std::isfinite(pq) ? SolveStatus::NotPositiveDefinite : SolveStatus::NumericalError;
      double rz_new = 0.0;
      rr = update(M, rz / pq, x, r, rb, zb, rz_new);
      if (!std::isfinite(rr)) return SolveStatus::NumericalError;
      if (rr <= goal2 && opt_.tolerance < kCheckBelow && checked != it) {
        // A tolerance near the recursion's drift: the residual taken afresh decides.
        checked = it;
        rr = true_residual(M, b, x, r, n);
      }
      if (rr <= goal2) {
        residual_ = std::sqrt(rr) / bnorm;
        return SolveStatus::Ok;
      }
      beta = rz_new / rz;
      rz = rz_new;
    }
    residual_ = std::sqrt(rr) / bnorm;
    return SolveStatus::NotConverged;
  }

  // The operator's product A' p' (with turn, p' = z' + beta p' first): t = (E + L^T)^-1 p' and
  // u = (E + L)^-1 (p' + (D - 2E) t) into t_ and u_, A t into at_, and with kFresh the residual
  // r afresh; returns p' . A' p' = p' . t + p' . u. Backward, the cluster (last in the order),
  // the separator, then the two parts at once, each of which goes on forward through its own
  // rows (a part's lower blocks are its own); forward, the separator and the cluster after them.
  template <bool kFresh, class T>
  double product(const Bsr<T>& M, bool turn, double beta, double* pb, const double* zb, double* rb,
                 double* r) {
    double* t = t_.data();
    double* u = u_.data();
    double* at = at_.data();
    if (turn) {
      next_direction(beta, pb, zb, separator());
      for (int c : cluster_) direction_row(beta, pb, zb, c);
    }
    const double pt_c = backward_cluster(M, pb, t);
    for (int c : cluster_) u[3 * c] = u[3 * c + 1] = u[3 * c + 2] = 0.0;
    // The cluster is last in the order: its columns are no row's lower part, so r'_C is out of
    // the rows' sums (put back by forward_cluster) as t_C and u_C are.
    if constexpr (kFresh) {
      gather_cluster(rb, crb_.data());
      for (int c : cluster_) rb[3 * c] = rb[3 * c + 1] = rb[3 * c + 2] = 0.0;
    }
    V4 pt_s[2] = {}, pu_s[2] = {};  // the separator's
    backward_rows(M, pb, t, separator(), Rows{}, pt_s);
    auto sweep = [&](Rows a, Rows b, double* sums) {
      if (turn) {
        next_direction(beta, pb, zb, a);
        next_direction(beta, pb, zb, b);
      }
      V4 pt[2] = {}, pu[2] = {};
      backward_rows(M, pb, t, a, b, pt);
      forward_rows<kFresh>(M, pb, t, u, at, rb, zb, r, a, b, pu);
      sums[0] = sum3(pt[0]) + sum3(pu[0]);
      sums[1] = sum3(pt[1]) + sum3(pu[1]);
    };
    both_parts(sweep);
    forward_rows<kFresh>(M, pb, t, u, at, rb, zb, r, separator(), Rows{}, pu_s);
    const double pu_c = forward_cluster<kFresh>(M, pb, t, u, at, rb, zb, r);
    return pt_c + sum3(pt_s[0]) + part_sum_[0] + part_sum_[1] + sum3(pu_s[0]) + pu_c;
  }

  // p' = z' + beta p' on `rows` outside the cluster, and on one row.
  void next_direction(double beta, double* pb, const double* zb, Rows rows) const {
    for (int i = rows.begin; i < rows.end; ++i)
      if (kind_[order_[i]] != kCluster) direction_row(beta, pb, zb, order_[i]);
  }
  static void direction_row(double beta, double* pb, const double* zb, int br) {
    for (int c = 3 * br; c < 3 * br + 3; ++c) pb[c] = zb[c] + beta * pb[c];
  }

  // r = b - A x and r' = (E + L)^-1 r in one pass over the matrix (row i's product needs x
  // only; its lower solve, the rows before it), returning r . r: the two parts at once, then
  // the separator. The cluster's columns are left out of the rows' products (x_C = 0 in the
  // padded copy) and added from the cluster's own blocks, as the sweeps do.
  template <class T>
  double residual_and_lower_solve(const Bsr<T>& M, const double* b, const double* x, double* r, double* y) {
    double* x0 = x0_.data();
    std::copy(x, x + n_, x0);
    gather_cluster(x0, cx_.data());
    for (int c : cluster_) {
      x0[3 * c] = x0[3 * c + 1] = x0[3 * c + 2] = 0.0;
      y[3 * c] = y[3 * c + 1] = y[3 * c + 2] = 0.0;
    }
    cluster_to_touched(M, cx_.data());
    auto lower = [&](Rows one, Rows two, double* sums) {
      V4 rr[2] = {};
      residual_rows(M, b, x0, r, y, one, two, rr);
      sums[0] = sum3(rr[0]);
      sums[1] = sum3(rr[1]);
    };
    both_parts(lower);
    V4 rr_s[2] = {};
    residual_rows(M, b, x0, r, y, separator(), Rows{}, rr_s);
    double rr_sum = part_sum_[0] + part_sum_[1] + sum3(rr_s[0]);
    if (cluster_.empty()) return rr_sum;
    // r_C = b_C - A_CN x_N - D_C x_C, y_C = D_C^-1 (r_C - A_CN y_N).
    const int m = 3 * static_cast<int>(cluster_.size());
    cholesky_multiply(dense_.data(), m, cx_.data(), cz_.data(), ctmp_.data());
    for_cluster_blocks(M, [&](int j, const T* B, int a) { add_block(B, x0 + 3 * j, cz_.data() + 3 * a); });
    for (size_t a = 0; a < cluster_.size(); ++a)
      for (int c = 0; c < 3; ++c) {
        const int i = 3 * cluster_[a] + c, l = 3 * static_cast<int>(a) + c;
        r[i] = b[i] - cz_[l];
        rr_sum += r[i] * r[i];
        cz_[l] = r[i];
      }
    for_cluster_blocks(M, [&](int j, const T* B, int a) {
      double* s = cz_.data() + 3 * a;
      sub_block(B, y + 3 * j, s);
    });
    cholesky_solve(dense_.data(), m, cz_.data());
    scatter_cluster(cz_.data(), y);
    return rr_sum;
  }

  // residual_and_lower_solve on the rows of `one` and `two` outside the cluster (in_turn);
  // adds their r . r to rr[0] and rr[1].
  template <class T>
  void residual_rows(const Bsr<T>& M, const double* b, const double* x0, double* r, double* y, Rows one,
                     Rows two, V4* rr) const {
    constexpr int K = Bsr<T>::kBlock;
    const T* val = M.val.data();
    const int* xoff = M.xoff.data();
    in_turn<false>(one, two, [&](int br, int which) __attribute__((always_inline)) {
      const int kind = kind_[br];
      if (kind == kCluster) return;
      V4 ax = kind == kTouched ? load4(w_.data() + 3 * br) : V4{};  // A x
      V4 s{};                                                       // -L y
      const int k0 = M.rowptr[br], kd = M.dblk[br], k1 = M.rowptr[br + 1];
      for (int k = k0; k < kd; ++k) {
        const T* B = val + K * k;
        ax += block_times(B, x0 + xoff[k]);
        s -= block_times(B, y + xoff[k]);
      }
      for (int k = kd; k < k1; ++k) ax += block_times(val + K * k, x0 + xoff[k]);
      const V4 bi{b[3 * br], b[3 * br + 1], b[3 * br + 2], 0.0};
      const V4 ri = bi - ax;  // lane 3 is 0
      store3(r + 3 * br, ri);
      rr[which] += ri * ri;
      store3(y + 3 * br, block_times(M.dinv.data() + 12 * br, ri + s));
    });
  }

  // w_j = A_jC v_C for every row j the cluster reaches.
  template <class T>
  void cluster_to_touched(const Bsr<T>& M, const double* vc) {
    for (int j : touched_) w_[3 * j] = w_[3 * j + 1] = w_[3 * j + 2] = 0.0;
    for_cluster_blocks(M, [&](int j, const T* B, int a) { add_block_t(B, vc + 3 * a, w_.data() + 3 * j); });
  }

  // r = b - A x, returning r . r.
  template <class T>
  double true_residual(const Bsr<T>& M, const double* b, const double* x, double* r, int n) {
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
  double update(const Bsr<T>& M, double alpha, double* x, double* r, double* rb, double* zb, double& rz) {
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
  double update_range(double alpha, double* x, double* r, double* rb, int i0, int i1) const {
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
  double multiply_d(const Bsr<T>& M, const double* r, double* z, int lo, int hi) const {
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

  // z_C = D_C r_C, returning r_C . z_C.
  double multiply_cluster_d(const double* r, double* z) {
    if (cluster_.empty()) return 0.0;
    const int m = 3 * static_cast<int>(cluster_.size());
    gather_cluster(r, cz_.data());
    cholesky_multiply(dense_.data(), m, cz_.data(), cw_.data(), ctmp_.data());
    double rz = 0.0;
    for (int i = 0; i < m; ++i) rz += cz_[i] * cw_[i];
    scatter_cluster(cw_.data(), z);
    return rz;
  }

  // The sweeps' row order, for two threads: the cloth's rows in two parts that share no block,
  // then the separator between them, then the hubs (always in the cluster). The sweeps take
  // the parts at once and the separator after them (forward) or before them (backward). The
  // parts are the mesh's first and second half, less the rows of the first that reach the
  // second (a grid's middle row): so the two threads' rows, and their vectors' entries, meet
  // in memory at one place only (on the pinched 4050-triangle square, split so, an iteration's
  // update took 9 us; split along a diagonal, whose cache lines the two cores share on every
  // mesh row, 17 us). A mesh numbered so that this separator is large is split by levels instead
  // (split_by_levels). Within a part the order is the mesh's. (Each part taken as two runs in
  // turn, so that a sweep advances two chains of rows at once, cost more iterations than it
  // saved: 9.2 -> 9.8 a step on the pinched 4050-triangle square, 7.0 -> 7.8 on the released
  // 15842-triangle one, for 4-7% less time per iteration.)
  void sweep_order(const SymCsr& A, const std::vector<int>& hub_rows) {
    const int nb = A.n / 3;
    std::vector<char> hub(nb, 0);
    for (int h : hub_rows) hub[h] = 1;
    std::array<std::vector<int>, 3> rows;  // part 0, part 1, separator; each in the mesh's order
    int cloth = 0;
    for (int br = 0; br < nb; ++br) cloth += !hub[br];
    for (int br = 0, seen = 0; br < nb; ++br) {
      if (hub[br]) continue;
      const bool first = 2 * seen++ < cloth;
      rows[first ? 0 : 1].push_back(br);
    }
    std::vector<char> second(nb, 0);
    for (int br : rows[1]) second[br] = 1;
    std::vector<int> inner;
    for (int br : rows[0]) {
      const int o = A.rowptr[3 * br], len = A.rowptr[3 * br + 1] - o;
      bool reaches = false;
      for (int k = 0; k < len && !reaches; k += 3) reaches = second[A.col[o + k] / 3] != 0;
      (reaches ? rows[2] : inner).push_back(br);
    }
    rows[0].swap(inner);
    split_ = rows[1].empty() ? nb : rows[1].front();
    if (8 * static_cast<int>(rows[2].size()) > cloth) {
      rows = split_by_levels(A, hub);
      split_ = nb / 2;
    }
    split_ &= ~3;  // 3 split_ a multiple of 4: update's second range starts a 4-lane run
    order_.clear();
    for (int q = 0; q < 3; ++q) {
      seg_[q] = static_cast<int>(order_.size());
      order_.insert(order_.end(), rows[q].begin(), rows[q].end());
    }
    seg_[3] = static_cast<int>(order_.size());
    order_.insert(order_.end(), hub_rows.begin(), hub_rows.end());
    rank_.assign(nb, 0);
    for (int i = 0; i < nb; ++i) rank_[order_[i]] = i;
    check_parts_apart(A, hub);
  }

  // The two parts' sweeps run at once on two threads: a block joining them would be a data race
  // (and results that depend on timing). Checked once per pattern; throws std::logic_error.
  void check_parts_apart(const SymCsr& A, const std::vector<char>& hub) const {
    std::vector<signed char> part(A.n / 3, -1);
    for (int q = 0; q < 2; ++q)
      for (int i = seg_[q]; i < seg_[q + 1]; ++i) part[order_[i]] = static_cast<signed char>(q);
    for (int i = seg_[0]; i < seg_[2]; ++i) {
      const int br = order_[i], o = A.rowptr[3 * br], len = A.rowptr[3 * br + 1] - o;
      for (int k = 0; k < len; k += 3) {
        const int j = A.col[o + k] / 3;
        if (!hub[j] && part[j] >= 0 && part[j] != part[br])
          throw std::logic_error("pcg: block rows " + std::to_string(br) + " and " + std::to_string(j) +
                                 " join the two parts of the sweeps");
      }
    }
  }

  // Two parts and their separator from a breadth-first level structure (from a pseudo-
  // peripheral row of each connected piece): a row's blocks reach its own level and the two
  // beside it only, so the level at which the count of rows passes half parts the levels before
  // it from those after it. Each in the mesh's order.
  static std::array<std::vector<int>, 3> split_by_levels(const SymCsr& A, const std::vector<char>& hub) {
    const int nb = A.n / 3;
    std::vector<int> level(nb, -1), queue;
    queue.reserve(nb);
    auto bfs = [&](int from, int base) {  // levels from base; returns the last row reached
      queue.assign(1, from);
      level[from] = base;
      for (size_t h = 0; h < queue.size(); ++h) {
        const int br = queue[h], o = A.rowptr[3 * br], len = A.rowptr[3 * br + 1] - o;
        for (int k = 0; k < len; k += 3) {
          const int j = A.col[o + k] / 3;
          if (hub[j] || level[j] >= 0) continue;
          level[j] = level[br] + 1;
          queue.push_back(j);
        }
      }
      return queue.back();
    };
    int levels = 0;  // each connected piece gets levels after the last one's
    for (int br = 0; br < nb; ++br) {
      if (hub[br] || level[br] >= 0) continue;
      const int far = bfs(br, levels);  // the farthest row from br starts the piece's levels
      for (int j : queue) level[j] = -1;
      bfs(far, levels);
      for (int j : queue) levels = std::max(levels, level[j] + 1);
    }
    std::vector<int> count(levels + 1, 0);
    int cloth = 0;
    for (int br = 0; br < nb; ++br)
      if (!hub[br]) ++count[level[br]], ++cloth;
    int mid = 0;
    for (int below = 0; mid < levels; ++mid) {
      below += count[mid];
      if (2 * below >= cloth) break;
    }
    std::array<std::vector<int>, 3> rows;
    for (int br = 0; br < nb; ++br)
      if (!hub[br]) rows[level[br] < mid ? 0 : level[br] > mid ? 1 : 2].push_back(br);
    return rows;
  }

  // The cluster's part of the backward sweep: t_C = D_C^-1 p_C (it is last in the order), and
  // its share A_jC t_C in the rows j it reaches; returns p_C . t_C. t_C is left in ct_, and 0
  // in t for the rows' sweeps.
  template <class T>
  double backward_cluster(const Bsr<T>& M, const double* p, double* t) {
    if (cluster_.empty()) return 0.0;
    double pt = 0.0;
    const int m = 3 * static_cast<int>(cluster_.size());
    gather_cluster(p, ct_.data());
    cholesky_solve(dense_.data(), m, ct_.data());
    for (size_t a = 0; a < cluster_.size(); ++a)
      for (int c = 0; c < 3; ++c) pt += ct_[3 * a + c] * p[3 * cluster_[a] + c];
    cluster_to_touched(M, ct_.data());
    for (int c : cluster_) t[3 * c] = t[3 * c + 1] = t[3 * c + 2] = 0.0;
    return pt;
  }

  // t = (E + L^T)^-1 p on the rows of `one` and `two` outside the cluster, each last to first
  // (in_turn; the rows after them done); adds their p . t to dot[0] and dot[1].
  template <class T>
  void backward_rows(const Bsr<T>& M, const double* p, double* t, Rows one, Rows two, V4* dot) const {
    constexpr int K = Bsr<T>::kBlock;
    const T* val = M.val.data();
    const int* xoff = M.xoff.data();
    const double* dinv = M.dinv.data();
    in_turn<true>(one, two, [&](int br, int which) __attribute__((always_inline)) {
      const int kind = kind_[br];
      if (kind == kCluster) return;
      const V4 pi = load3(p + 3 * br);  // the next row's p may be the other part's, in its turn
      V4 s = pi;
      if (kind == kTouched) s -= load4(w_.data() + 3 * br);
      // Farthest block first: the nearest row's t, computed last, then waits on one product.
      for (int k = M.rowptr[br + 1] - 1; k > M.dblk[br]; --k) s -= block_times(val + K * k, t + xoff[k]);
      const V4 ti = block_times(dinv + 12 * br, s);  // lane 3 is 0
      store3(t + 3 * br, ti);
      dot[which] += pi * ti;
    });
  }

  // After the backward sweep, on the rows of `one` and `two` outside the cluster (in_turn; the
  // rows before them done): u = (E + L)^-1 (p + (D - 2E) t), A t = L t + p + (D - E) t, and
  // with kFresh the residual r = E r' + L r' from the transformed one (z' = E r' given); adds
  // their p . u to dot[0] and dot[1].
  template <bool kFresh, class T>
  void forward_rows(const Bsr<T>& M, const double* p, const double* t, double* u, double* at,
                    const double* rb, const double* zb, double* r, Rows one, Rows two, V4* dot) const {
    constexpr int K = Bsr<T>::kBlock;
    const V4 c_dt_u = splat(2.0 / omega_ - 1.0), c_dt_a = splat(1.0 - 1.0 / omega_);
    in_turn<false>(one, two, [&](int br, int which) __attribute__((always_inline)) {
      if (kind_[br] == kCluster) return;
      const V4 pi = load3(p + 3 * br);  // the next row's p may be the other part's, in its turn
      const V4 dt = block_times(M.val.data() + K * M.dblk[br], t + 3 * br);
      V4 s = pi - c_dt_u * dt;        // p + (D - 2E) t - L u
      V4 a = pi + c_dt_a * dt;        // p + (D - E) t + L t
      V4 g = load4(zb + 3 * br);      // E r' + L r'
      const T* B = M.val.data() + K * M.rowptr[br];
      for (int k = M.rowptr[br]; k < M.dblk[br]; ++k, B += K) {
        const int o = M.xoff[k];
        a += block_times(B, t + o);
        if constexpr (kFresh) g += block_times(B, rb + o);
        s -= block_times(B, u + o);
      }
      store3(at + 3 * br, a);
      if constexpr (kFresh) store3(r + 3 * br, g);
      const V4 ui = block_times(M.dinv.data() + 12 * br, s);  // lane 3 is 0
      store3(u + 3 * br, ui);
      dot[which] += pi * ui;
    });
  }

  // The cluster's part of the forward sweep, after the rows': u_C, A t_C and with kFresh r_C;
  // t_C back in t (and r'_C in rb); returns p_C . u_C.
  template <bool kFresh, class T>
  double forward_cluster(const Bsr<T>& M, const double* p, double* t, double* u, double* at, double* rb,
                         const double* zb, double* r) {
    if (cluster_.empty()) return 0.0;
    // The cluster's block is not relaxed (omega 1: over-relaxing the contact springs cost
    // iterations), so t_C = D_C^-1 p_C, p_C - D_C t_C = 0: u_C = D_C^-1 (0 - A_CN u_N), A t_C =
    // A_CN t_N + p_C, r_C = D_C r'_C + A_CN r'_N.
    const int m = 3 * static_cast<int>(cluster_.size());
    std::fill(cz_.begin(), cz_.begin() + m, 0.0);
    std::fill(cw_.begin(), cw_.begin() + m, 0.0);
    gather_cluster(zb, ctmp_.data());
    for_cluster_blocks(M, [&](int j, const T* B, int a) {
      sub_block(B, u + 3 * j, cz_.data() + 3 * a);
      add_block(B, t + 3 * j, cw_.data() + 3 * a);
      add_block(B, rb + 3 * j, ctmp_.data() + 3 * a);
    });
    cholesky_solve(dense_.data(), m, cz_.data());
    if constexpr (kFresh) scatter_cluster(crb_.data(), rb);
    double pu = 0.0;
    for (size_t a = 0; a < cluster_.size(); ++a)
      for (int c = 0; c < 3; ++c) {
        const int i = 3 * cluster_[a] + c, l = 3 * static_cast<int>(a) + c;
        u[i] = cz_[l];
        at[i] = cw_[l] + p[i];
        if constexpr (kFresh) r[i] = ctmp_[l];
        t[i] = ct_[l];
        pu += p[i] * u[i];
      }
    return pu;
  }

  // f(j, B, a) for every block B = A_{C_a, j}^T... the coupling blocks between cluster node a
  // and a node j outside the cluster, each once, as stored (A_{a j} column-major: B^T x is
  // A_{j a} x by symmetry).
  template <class T, class F>
  void for_cluster_blocks(const Bsr<T>& M, F&& f) const {
    constexpr int K = Bsr<T>::kBlock;
    for (size_t a = 0; a < cluster_.size(); ++a) {
      const int c = cluster_[a];
      if (M.is_hub[c]) continue;
      const T* B = M.val.data() + K * M.rowptr[c];
      for (int k = M.rowptr[c]; k < M.rowptr[c + 1]; ++k, B += K) {
        const int j = M.xoff[k] / 3;
        if (kind_[j] != kCluster) f(j, B, static_cast<int>(a));
      }
    }
    for (size_t i = 0; i < M.hubs.size(); ++i) {
      const int h = M.hubs[i];
      if (local_[h] < 0) continue;
      for (int e = M.hub_ptr[i]; e < M.hub_ptr[i + 1]; ++e) {
        const int j = M.hub_col[e];
        if (kind_[j] != kCluster) f(j, M.hub_val.data() + K * e, local_[h]);
      }
    }
  }

  void gather_cluster(const double* v, double* c) const {
    for (size_t a = 0; a < cluster_.size(); ++a)
      for (int k = 0; k < 3; ++k) c[3 * a + k] = v[3 * cluster_[a] + k];
  }
  void scatter_cluster(const double* c, double* v) const {
    for (size_t a = 0; a < cluster_.size(); ++a)
      for (int k = 0; k < 3; ++k) v[3 * cluster_[a] + k] = c[3 * a + k];
  }

  // The preconditioner's dense block: the hub rows (proxies) with the nodes their non-zero
  // blocks reach (the vertices in contact), at most kMaxCluster nodes, strongest coupling
  // first. Block-Jacobi alone leaves a vertex's stiff contact to its proxy to the iterations:
  // on the pinched 968-triangle square that doubled them. Returns false if the block is not
  // positive definite.
  template <class T>
  bool factor_cluster(const Bsr<T>& M, const SymCsr& A) {
    for (int node : cluster_) {
      local_[node] = -1;
      kind_[node] = kPlain;
    }
    for (int node : touched_) kind_[node] = kPlain;
    touched_.clear();
    cluster_.clear();
    weight_.clear();
    for (std::size_t i = 0; i < M.hubs.size(); ++i)
      for (int k = M.hub_ptr[i]; k < M.hub_ptr[i + 1]; ++k) {
        const int hub = M.hubs[i], node = M.hub_col[k];
        const T* blk = M.hub_val.data() + Bsr<T>::kBlock * k;
        const double w = std::abs(double(blk[0])) + std::abs(double(blk[5])) + std::abs(double(blk[10]));
        if (node != hub && opt_.hub_block) weight_.push_back({-w, node});
      }
    for (int hub : hubs_) weight_.push_back({-std::numeric_limits<double>::infinity(), hub});
    std::sort(weight_.begin(), weight_.end());
    for (const auto& [w, node] : weight_) {
      if (static_cast<int>(cluster_.size()) == kMaxCluster) break;
      if (local_[node] >= 0) continue;
      local_[node] = static_cast<int>(cluster_.size());
      kind_[node] = kCluster;
      cluster_.push_back(node);
    }
    for_cluster_blocks(M, [&](int j, const T*, int) {
      if (kind_[j] == kTouched) return;
      kind_[j] = kTouched;
      touched_.push_back(j);
    });
    const int m = 3 * static_cast<int>(cluster_.size());
    std::fill(dense_.begin(), dense_.begin() + m * m, 0.0);
    if (ssor_) {
      cluster_from_copy(M);
    } else {
      for (int a : cluster_) {
        const int o = A.rowptr[3 * a], len = A.rowptr[3 * a + 1] - o;
        for (int k = 0; k < len; k += 3) {
          const int b = local_[A.col[o + k] / 3];
          if (b < 0) continue;
          for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c) dense_[(3 * local_[a] + r) * m + 3 * b + c] = A.val[o + r * len + k + c];
        }
      }
    }
    return cholesky(dense_.data(), m);
  }

  // In-place Cholesky A = L L^T of an m x m row-major matrix (lower triangle used). False if
  // it is not positive definite. Row-oriented, so every inner loop is a dot product of two
  // contiguous rows, which Eigen vectorizes (a plain loop reduction stays scalar without
  // -ffast-math): the factor of the 72 x 72 pinch block is a fixed cost of every solve.
  static bool cholesky(double* a, int m) {
    using Row = Eigen::Map<const Eigen::VectorXd>;
    for (int j = 0; j < m; ++j) {
      const Row lj(a + j * m, j);
      const double d = a[j * m + j] - lj.squaredNorm();
      if (!(d > 0.0) || !std::isfinite(d)) return false;
      const double l = std::sqrt(d);
      a[j * m + j] = l;
      for (int i = j + 1; i < m; ++i) a[i * m + j] = (a[i * m + j] - Row(a + i * m, j).dot(lj)) / l;
    }
    return true;
  }

  // SSOR's cluster block from the matrix copy, as its D must be (invert_diagonal): the cluster's
  // cloth rows' blocks, and the hub rows' (whose columns the cloth rows do not keep).
  template <class T>
  void cluster_from_copy(const Bsr<T>& M) {
    constexpr int K = Bsr<T>::kBlock;
    const int m = 3 * static_cast<int>(cluster_.size());
    auto put = [&](int a, int b, const T* B, bool transpose) {
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
          dense_[(3 * a + r) * m + 3 * b + c] = double(transpose ? B[4 * r + c] : B[4 * c + r]);
    };
    for (int node : cluster_) {
      if (M.is_hub[node]) continue;
      const T* B = M.val.data() + K * M.rowptr[node];
      for (int k = M.rowptr[node]; k < M.rowptr[node + 1]; ++k, B += K)
        if (local_[M.xoff[k] / 3] >= 0) put(local_[node], local_[M.xoff[k] / 3], B, false);
    }
    for (size_t i = 0; i < M.hubs.size(); ++i) {
      const int h = M.hubs[i];
      if (local_[h] < 0) continue;
      for (int e = M.hub_ptr[i]; e < M.hub_ptr[i + 1]; ++e) {
        const int j = M.hub_col[e];
        if (local_[j] < 0) continue;
        put(local_[h], local_[j], M.hub_val.data() + K * e, false);
        if (!M.is_hub[j]) put(local_[j], local_[h], M.hub_val.data() + K * e, true);
      }
    }
  }

  // y = L L^T x with the factor from cholesky() (tmp: m entries of workspace).
  static void cholesky_multiply(const double* l, int m, const double* x, double* y, double* tmp) {
    for (int j = 0; j < m; ++j) tmp[j] = 0.0;
    for (int i = 0; i < m; ++i)
      for (int j = 0; j <= i; ++j) tmp[j] += l[i * m + j] * x[i];
    for (int i = 0; i < m; ++i) {
      double s = 0.0;
      for (int j = 0; j <= i; ++j) s += l[i * m + j] * tmp[j];
      y[i] = s;
    }
  }

  // y = (L L^T)^-1 y with the factor from cholesky(): forward substitution by rows (dot
  // products), back substitution by rows of L, i.e. columns of L^T (an axpy per row), so both
  // read the factor contiguously. Once per PCG iteration.
  static void cholesky_solve(const double* l, int m, double* y) {
    using Row = Eigen::Map<const Eigen::VectorXd>;
    for (int i = 0; i < m; ++i)
      y[i] = (y[i] - Row(l + i * m, i).dot(Row(y, i))) / l[i * m + i];
    for (int i = m - 1; i >= 0; --i) {
      y[i] /= l[i * m + i];
      Eigen::Map<Eigen::VectorXd>(y, i) -= y[i] * Row(l + i * m, i);
    }
  }

  static constexpr int kMaxCluster = 24;
  static constexpr int kLoadChunks = 8;
  // SSOR: every kRefresh-th iteration the residual is taken afresh from r' (bounding the
  // drift of r -= alpha A t); at a tolerance below kCheckBelow, a converged one is checked.
  static constexpr int kRefresh = 8;
  static constexpr double kCheckBelow = 1e-6;
  static constexpr signed char kPlain = 0, kCluster = 1, kTouched = 2;
  std::vector<signed char> kind_;  // per block row: outside the cluster, in it, or reached by it
  std::vector<int> touched_;       // the rows the cluster reaches
  std::vector<char> listed_;       // per block row: in solve_changed's list (reload_hubs)
  std::vector<int> sorted_;        // that list, sorted
  std::vector<double> w_, t_, u_, at_;
  std::array<double, 3 * kMaxCluster> ct_{}, cw_{}, ctmp_{}, cx_{}, crb_{};
  std::vector<int> hubs_, local_, cluster_;
  std::vector<std::pair<double, int>> weight_;
  std::array<double, 9 * kMaxCluster * kMaxCluster> dense_{};
  std::array<double, 3 * kMaxCluster> cz_{};

  PcgOptions opt_;
  bool ssor_;  // the preconditioner is SSOR (else block-Jacobi)
  double omega_;  // SSOR's relaxation factor (the cloth rows'; the cluster's is 1)
  bool prepared_ = false, float_in_use_ = false;
  std::vector<double> guess_;  // the starting guess, for the double solve after a float one
  int n_ = 0;
  std::vector<double> r_, z_, p_, q_, x0_, inv_;
  std::vector<int> order_, rank_;  // the sweeps' row order, and each row's place in it
  std::array<int, 4> seg_{};       // order_'s parts: [seg_0, seg_1), [seg_1, seg_2); separator [seg_2, seg_3)
  std::array<double, 2> part_sum_{}, part_rz_{};  // the two threads' partial sums, added in order
  int split_ = 0;  // update's two ranges of block rows: [0, split_), [split_, nb)
  WorkerPool* pool_ = nullptr;
  Bsr<double> matrix_double_;
  Bsr<float> matrix_float_;
};

}  // namespace

std::unique_ptr<LinearSolver> make_pcg_solver(const PcgOptions& opt) {
  return std::make_unique<PcgSolver>(opt);
}

std::unique_ptr<LinearSolver> make_solver(const std::string& name, const PcgOptions& pcg) {
  if (name == "pcg") return make_pcg_solver(pcg);
  if (name == "cholmod") return make_cholmod_solver(CholmodMode::Simplicial);
  if (name == "cholmod-supernodal") return make_cholmod_solver(CholmodMode::Supernodal);
  throw std::invalid_argument("unknown solver '" + name + "' (pcg, cholmod, cholmod-supernodal)");
}

}  // namespace hapticloth::cloth
