#pragma once
// The preconditioned conjugate gradient solver of the step's system (eq. 9; PcgOptions). Its
// definitions are in four files, by concern:
//   pcg_solver.cpp    the driver: analysis, the solves and re-solves with the float copy's
//                     fallback to double, loading the block copy, block-Jacobi's iteration
//   pcg_ordering.cpp  the sweeps' row order: two parts that share no block, and a separator
//   pcg_ssor.cpp      SSOR's iteration (Eisenstat's trick): the backward and forward sweeps
//   pcg_cluster.cpp   the dense cluster of hub rows (the fingertip proxies): its Cholesky
//                     factor, its part of each sweep and of the products
// The solver is made through make_solver / make_pcg_solver (solver.hpp).
#include <array>
#include <optional>
#include <thread>
#include <utility>
#include <vector>

#include "cloth/pcg_blocks.hpp"
#include "cloth/solver.hpp"
#include "cloth/worker_pool.hpp"

namespace hapticloth::cloth::pcg {

class PcgSolver final : public LinearSolver {
 public:
  explicit PcgSolver(const PcgOptions& o);

  const char* name() const override { return "pcg"; }
  void use_pool(WorkerPool* pool) override { pool_ = pool; }
  void analyze(const SymCsr& A) override;

  // With the float copy, a system too ill-conditioned for its rounding (the residual stalls
  // above the tolerance: a 1000x stiffer cloth at a 20 ms step in hapticloth-bench stability)
  // is solved again with the double copy (its iterations are the ones reported).
  SolveStatus solve(const SymCsr& A, const double* b, double* x) override;

  // The matrix copy and the preconditioner of the last solve serve again.
  SolveStatus resolve(const SymCsr& A, const double* b, double* x) override;

  // The copy in use (the one the last solve prepared) gets the changed rows.
  SolveStatus solve_changed(const SymCsr& A, const int* block_rows, int count, const double* b,
                            double* x) override;

  // The changed rows reloaded as for a re-solve, then the cluster settled (settle_cluster) and
  // no iteration. Before any solve it is a whole solve.
  SolveStatus settle_changed(const SymCsr& A, const int* block_rows, int count, const double* b,
                             double* x) override;

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
  SolveStatus run(Bsr<T>& M, const SymCsr& A, const double* b, double* x, bool load);

  // A re-solve after a change in a few block rows: those rows reloaded and re-preconditioned,
  // the hubs' blocks reloaded and their dense block factored again. A contact revision then
  // reloads the rows of the vertices in contact and the hubs, not the whole matrix.
  template <class T>
  SolveStatus run_changed(Bsr<T>& M, const SymCsr& A, const int* rows, int count, const double* b,
                          double* x);

  // The listed rows reloaded and re-preconditioned, the hubs' blocks reloaded and the cluster
  // factored again; false if a block is not positive definite.
  template <class T>
  bool reload_changed(Bsr<T>& M, const SymCsr& A, const int* rows, int count);

  // The preconditioner's PCG from the guess in x.
  template <class T>
  SolveStatus iterate_preconditioned(const Bsr<T>& M, const double* b, double* x);

  // settle_changed's solve: the changed rows reloaded, then the cluster alone, no iteration
  // (residual() is left at 0: the rest of the rows are not looked at). Without a cluster, the
  // whole solve.
  template <class T>
  SolveStatus settle(Bsr<T>& M, const SymCsr& A, const int* rows, int count, const double* b, double* x);

  // The hub rows' blocks after a change in `rows` (Bsr::reload_hubs, which wants them sorted).
  template <class T>
  void reload_hubs(Bsr<T>& M, const SymCsr& A, const int* rows, int count);

  // The matrix copy, the block-Jacobi inverses and the hub block. False if a diagonal block or
  // the hub block is not positive definite.
  template <class T>
  bool prepare(Bsr<T>& M, const SymCsr& A);

  // The matrix copy, in kLoadChunks pieces of rows that the pool's two threads take in turn (a
  // late helper leaves the caller more of them), and the hub rows' blocks as one more piece,
  // the helper's first (a scan of the hubs' whole rows, which reach every node). False if a
  // diagonal block is not positive definite.
  template <class T>
  bool load(Bsr<T>& M, const SymCsr& A);

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
  bool invert_diagonal(const SymCsr& A, int br, int d);

  // Before the iterations, the cluster's rows (the proxies and the vertices they hold, the
  // preconditioner's dense block) solved with the rest of x held: x_C += A_CC^-1 (b - A x)_C,
  // one block Gauss-Seidel step. When contacts change, nearly all of the residual is there (a
  // proxy is massless, its springs the stiffest terms), and the PCG's first step, one length for
  // every row, takes off only a small factor of it (docs/performance.md, "The release's residual,
  // and a floor under the re-solve share"). Settled first, the script's stroke takes fewer
  // iterations (docs/performance.md, "The proxies' rows settled first"). Left as it is when
  // those rows are already within the goal, so that a solved guess stays exactly as it was
  // (the integrator's same-candidate test, Integrator::revise_contacts).
  template <class T>
  void settle_cluster(const Bsr<T>& M, const double* b, double* x, double goal2);

  // The squared residual that ends the solve: tolerance x the larger of |b| and the residual
  // scale (LinearSolver::set_residual_scale), squared.
  double goal_squared(double bn2) const;

  // |b|^2 into bn2 and a finite guess in x (else 0); a status if that settles the solve (b = 0
  // or not finite).
  static std::optional<SolveStatus> start(const double* b, double* x, int n, double& bn2);

  // Preconditioned conjugate gradients from the guess in x, until |r| <= tolerance |b|.
  template <class T>
  SolveStatus iterate(const Bsr<T>& M, const double* b, double* x, int n, int nb);

  // z = M^-1 r, returning r . z, with r . r in `rr`, in one pass. M is block-Jacobi (the 3x3
  // diagonal blocks' inverses) except on the cluster of hub rows and the nodes they touch, which
  // is one dense block (factor_cluster).
  double precondition(const double* r, double* z, int nb, double& rr);

  // Symmetric block Gauss-Seidel (SSOR) by Eisenstat's trick. A = L + D + L^T with D the 3x3
  // diagonal blocks and the cluster's dense block, the cluster ordered last, and E = D / omega
  // (the cluster's block unrelaxed); the preconditioner is M = (E + L) E^-1 (E + L^T), SSOR's
  // up to a factor. CG runs on A' = (E + L)^-1 A (E + L^T)^-1 with the preconditioner E, whose
  // product costs one backward and one forward sweep, each over half the blocks: with t =
  // (E + L^T)^-1 p', A' p' = t + (E + L)^-1 (p' + (D - 2E) t), from A = (E + L) + (E + L^T) +
  // D - 2E. So an iteration reads the matrix once, as block-Jacobi's does, and the cloth's
  // smooth modes converge in fewer (docs/performance.md, 'Performance of the step'). x is
  // carried along (x += alpha t), and so is the true residual r = b - A x (r -= alpha A t, the
  // forward sweep giving A t = L t + p' + (D - E) t), so the solve stops at |r| <= tolerance
  // |b| as block-Jacobi's does. That recursion drifts (A t is a difference of terms up to 1e8
  // times larger with stiff contact springs; test_solver PcgWithContactHubsMatchesCholmod), so every
  // kRefresh-th sweep also takes r = (E + L) r' = E r' + L r' afresh from the transformed one.
  // An iteration is two passes that the pool's two threads share (sweep_order): the product,
  // and the update with the next z' = E r'.
  template <class T>
  SolveStatus iterate_ssor(const Bsr<T>& M, const double* b, double* x, int n, int nb);

  // The operator's product A' p' (with turn, p' = z' + beta p' first): t = (E + L^T)^-1 p' and
  // u = (E + L)^-1 (p' + (D - 2E) t) into t_ and u_, A t into at_, and with kFresh the residual
  // r afresh; returns p' . A' p' = p' . t + p' . u. Backward, the cluster (last in the order),
  // the separator, then the two parts at once, each of which goes on forward through its own
  // rows (a part's lower blocks are its own); forward, the separator and the cluster after them.
  template <bool kFresh, class T>
  double product(const Bsr<T>& M, bool turn, double beta, double* pb, const double* zb, double* rb,
                 double* r);

  // p' = z' + beta p' on `rows` outside the cluster, and on one row.
  void next_direction(double beta, double* pb, const double* zb, Rows rows) const;

  static void direction_row(double beta, double* pb, const double* zb, int br);

  // r = b - A x and r' = (E + L)^-1 r in one pass over the matrix (row i's product needs x
  // only; its lower solve, the rows before it), returning r . r: the two parts at once, then
  // the separator. The cluster's columns are left out of the rows' products (x_C = 0 in the
  // padded copy) and added from the cluster's own blocks, as the sweeps do.
  template <class T>
  double residual_and_lower_solve(const Bsr<T>& M, const double* b, const double* x, double* r, double* y);

  // residual_and_lower_solve on the rows of `one` and `two` outside the cluster (in_turn);
  // adds their r . r to rr[0] and rr[1].
  template <class T>
  void residual_rows(const Bsr<T>& M, const double* b, const double* x0, double* r, double* y, Rows one,
                     Rows two, V4* rr) const;

  // w_j = A_jC v_C for every row j the cluster reaches.
  template <class T>
  void cluster_to_touched(const Bsr<T>& M, const double* vc);

  // r = b - A x, returning r . r.
  template <class T>
  double true_residual(const Bsr<T>& M, const double* b, const double* x, double* r, int n);

  // x += alpha t, r -= alpha A t, r' -= alpha (t + u) (= A' p'), then z' = E r': block rows
  // [0, split_) and [split_, nb) at once, in 4-lane runs of entries (with the parts split by
  // number, each range on the thread whose part it holds, its data in that core's cache); the
  // cluster's z' after. Returns r . r, and r' . z' in rz.
  template <class T>
  double update(const Bsr<T>& M, double alpha, double* x, double* r, double* rb, double* zb, double& rz);

  // update's vector part on the entries [i0, i1) (i0 a multiple of 4), returning their r . r.
  double update_range(double alpha, double* x, double* r, double* rb, int i0, int i1) const;

  // z = E r (the 3x3 diagonal blocks over omega) on block rows [lo, hi) outside the cluster,
  // returning their r . z.
  template <class T>
  double multiply_d(const Bsr<T>& M, const double* r, double* z, int lo, int hi) const;

  // z_C = D_C r_C, returning r_C . z_C.
  double multiply_cluster_d(const double* r, double* z);

  // The sweeps' row order, for two threads: the cloth's rows in two parts that share no block,
  // then the separator between them, then the hubs (always in the cluster). The sweeps take
  // the parts at once and the separator after them (forward) or before them (backward). The
  // parts are the mesh's first and second half, less the rows of the first that reach the
  // second (a grid's middle row): so the two threads' rows, and their vectors' entries, meet
  // in memory at one place only (split along a diagonal instead, the two cores share cache lines
  // on every mesh row, and the update is slower: docs/performance.md, 'Performance of the step').
  // A mesh numbered so that this separator is large is split by levels instead
  // (split_by_levels). Within a part the order is the mesh's. (Each part taken as two runs in
  // turn, so that a sweep advances two chains of rows at once, makes an iteration cheaper but
  // takes more iterations than that saves: BENCHMARKS.md, 'The limit'.)
  void sweep_order(const SymCsr& A, const std::vector<int>& hub_rows);

  // The two parts' sweeps run at once on two threads: a block joining them would be a data race
  // (and results that depend on timing). Checked once per pattern; throws std::logic_error.
  void check_parts_apart(const SymCsr& A, const std::vector<char>& hub) const;

  // Two parts and their separator from a breadth-first level structure (from a pseudo-
  // peripheral row of each connected piece): a row's blocks reach its own level and the two
  // beside it only, so the level at which the count of rows passes half parts the levels before
  // it from those after it. Each in the mesh's order.
  static std::array<std::vector<int>, 3> split_by_levels(const SymCsr& A, const std::vector<char>& hub);

  // The cluster's part of the backward sweep: t_C = D_C^-1 p_C (it is last in the order), and
  // its share A_jC t_C in the rows j it reaches; returns p_C . t_C. t_C is left in ct_, and 0
  // in t for the rows' sweeps.
  template <class T>
  double backward_cluster(const Bsr<T>& M, const double* p, double* t);

  // t = (E + L^T)^-1 p on the rows of `one` and `two` outside the cluster, each last to first
  // (in_turn; the rows after them done); adds their p . t to dot[0] and dot[1].
  template <class T>
  void backward_rows(const Bsr<T>& M, const double* p, double* t, Rows one, Rows two, V4* dot) const;

  // After the backward sweep, on the rows of `one` and `two` outside the cluster (in_turn; the
  // rows before them done): u = (E + L)^-1 (p + (D - 2E) t), A t = L t + p + (D - E) t, and
  // with kFresh the residual r = E r' + L r' from the transformed one (z' = E r' given); adds
  // their p . u to dot[0] and dot[1].
  template <bool kFresh, class T>
  void forward_rows(const Bsr<T>& M, const double* p, const double* t, double* u, double* at,
                    const double* rb, const double* zb, double* r, Rows one, Rows two, V4* dot) const;

  // The cluster's part of the forward sweep, after the rows': u_C, A t_C and with kFresh r_C;
  // t_C back in t (and r'_C in rb); returns p_C . u_C.
  template <bool kFresh, class T>
  double forward_cluster(const Bsr<T>& M, const double* p, double* t, double* u, double* at, double* rb,
                         const double* zb, double* r);

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
  void gather_cluster(const double* v, double* c) const;

  void scatter_cluster(const double* c, double* v) const;

  // The preconditioner's dense block: the hub rows (proxies) with the nodes their non-zero
  // blocks reach (the vertices in contact), at most kMaxCluster nodes, strongest coupling
  // first. Block-Jacobi alone leaves a vertex's stiff contact to its proxy to the iterations,
  // which then take many more (test_solver PcgWithContactHubsMatchesCholmod). Returns false if the
  // block is not positive definite.
  template <class T>
  bool factor_cluster(const Bsr<T>& M, const SymCsr& A);

  // In-place Cholesky A = L L^T of an m x m row-major matrix (lower triangle used). False if
  // it is not positive definite. Row-oriented, so every inner loop is a dot product of two
  // contiguous rows, which Eigen vectorizes (a plain loop reduction stays scalar without
  // -ffast-math): the factor of the 72 x 72 pinch block is a fixed cost of every solve.
  static bool cholesky(double* a, int m);

  // SSOR's cluster block from the matrix copy, as its D must be (invert_diagonal): the cluster's
  // cloth rows' blocks, and the hub rows' (whose columns the cloth rows do not keep).
  template <class T>
  void cluster_from_copy(const Bsr<T>& M);

  // y = L L^T x with the factor from cholesky() (tmp: m entries of workspace).
  static void cholesky_multiply(const double* l, int m, const double* x, double* y, double* tmp);

  // y = (L L^T)^-1 y with the factor from cholesky(): forward substitution by rows (dot
  // products), back substitution by rows of L, i.e. columns of L^T (an axpy per row), so both
  // read the factor contiguously. Once per PCG iteration.
  static void cholesky_solve(const double* l, int m, double* y);

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

}  // namespace hapticloth::cloth::pcg
