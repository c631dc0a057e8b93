// SSOR's iteration of the PCG solver (pcg_solver.hpp), with Eisenstat's trick: one backward and
// one forward sweep per product, the two parts of the order at once.
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
SolveStatus PcgSolver::iterate_ssor(const Bsr<T>& M, const double* b, double* x, int n, int nb) {
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
double PcgSolver::product(const Bsr<T>& M, bool turn, double beta, double* pb, const double* zb, double* rb,
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
void PcgSolver::next_direction(double beta, double* pb, const double* zb, Rows rows) const {
  for (int i = rows.begin; i < rows.end; ++i)
    if (kind_[order_[i]] != kCluster) direction_row(beta, pb, zb, order_[i]);
}

void PcgSolver::direction_row(double beta, double* pb, const double* zb, int br) {
  for (int c = 3 * br; c < 3 * br + 3; ++c) pb[c] = zb[c] + beta * pb[c];
}

// r = b - A x and r' = (E + L)^-1 r in one pass over the matrix (row i's product needs x
// only; its lower solve, the rows before it), returning r . r: the two parts at once, then
// the separator. The cluster's columns are left out of the rows' products (x_C = 0 in the
// padded copy) and added from the cluster's own blocks, as the sweeps do.
template <class T>
double PcgSolver::residual_and_lower_solve(const Bsr<T>& M, const double* b, const double* x, double* r, double* y) {
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
void PcgSolver::residual_rows(const Bsr<T>& M, const double* b, const double* x0, double* r, double* y, Rows one,
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

// t = (E + L^T)^-1 p on the rows of `one` and `two` outside the cluster, each last to first
// (in_turn; the rows after them done); adds their p . t to dot[0] and dot[1].
template <class T>
void PcgSolver::backward_rows(const Bsr<T>& M, const double* p, double* t, Rows one, Rows two, V4* dot) const {
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
void PcgSolver::forward_rows(const Bsr<T>& M, const double* p, const double* t, double* u, double* at,
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

// The float and double copies' instantiations, for the other files of the solver.
template SolveStatus PcgSolver::iterate_ssor<float>(const Bsr<float>& M, const double* b, double* x, int n, int nb);
template SolveStatus PcgSolver::iterate_ssor<double>(const Bsr<double>& M, const double* b, double* x, int n, int nb);
template double PcgSolver::product<false, float>(const Bsr<float>& M, bool turn, double beta, double* pb, const double* zb, double* rb,
                 double* r);
template double PcgSolver::product<false, double>(const Bsr<double>& M, bool turn, double beta, double* pb, const double* zb, double* rb,
                 double* r);
template double PcgSolver::product<true, float>(const Bsr<float>& M, bool turn, double beta, double* pb, const double* zb, double* rb,
                 double* r);
template double PcgSolver::product<true, double>(const Bsr<double>& M, bool turn, double beta, double* pb, const double* zb, double* rb,
                 double* r);
template double PcgSolver::residual_and_lower_solve<float>(const Bsr<float>& M, const double* b, const double* x, double* r, double* y);
template double PcgSolver::residual_and_lower_solve<double>(const Bsr<double>& M, const double* b, const double* x, double* r, double* y);
template void PcgSolver::residual_rows<float>(const Bsr<float>& M, const double* b, const double* x0, double* r, double* y, Rows one,
                     Rows two, V4* rr) const;
template void PcgSolver::residual_rows<double>(const Bsr<double>& M, const double* b, const double* x0, double* r, double* y, Rows one,
                     Rows two, V4* rr) const;
template void PcgSolver::backward_rows<float>(const Bsr<float>& M, const double* p, double* t, Rows one, Rows two, V4* dot) const;
template void PcgSolver::backward_rows<double>(const Bsr<double>& M, const double* p, double* t, Rows one, Rows two, V4* dot) const;
template void PcgSolver::forward_rows<false, float>(const Bsr<float>& M, const double* p, const double* t, double* u, double* at,
                    const double* rb, const double* zb, double* r, Rows one, Rows two, V4* dot) const;
template void PcgSolver::forward_rows<false, double>(const Bsr<double>& M, const double* p, const double* t, double* u, double* at,
                    const double* rb, const double* zb, double* r, Rows one, Rows two, V4* dot) const;
template void PcgSolver::forward_rows<true, float>(const Bsr<float>& M, const double* p, const double* t, double* u, double* at,
                    const double* rb, const double* zb, double* r, Rows one, Rows two, V4* dot) const;
template void PcgSolver::forward_rows<true, double>(const Bsr<double>& M, const double* p, const double* t, double* u, double* at,
                    const double* rb, const double* zb, double* r, Rows one, Rows two, V4* dot) const;

}  // namespace hapticloth::cloth::pcg
