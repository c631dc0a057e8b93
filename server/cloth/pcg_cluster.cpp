// The dense cluster of the PCG solver (pcg_solver.hpp): the hub rows (fingertip proxies) as one
// dense block, its Cholesky factor, and its part of the sweeps and products.
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
void PcgSolver::settle_cluster(const Bsr<T>& M, const double* b, double* x, double goal2) {
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

// w_j = A_jC v_C for every row j the cluster reaches.
template <class T>
void PcgSolver::cluster_to_touched(const Bsr<T>& M, const double* vc) {
  for (int j : touched_) w_[3 * j] = w_[3 * j + 1] = w_[3 * j + 2] = 0.0;
  for_cluster_blocks(M, [&](int j, const T* B, int a) { add_block_t(B, vc + 3 * a, w_.data() + 3 * j); });
}

// z_C = D_C r_C, returning r_C . z_C.
double PcgSolver::multiply_cluster_d(const double* r, double* z) {
  if (cluster_.empty()) return 0.0;
  const int m = 3 * static_cast<int>(cluster_.size());
  gather_cluster(r, cz_.data());
  cholesky_multiply(dense_.data(), m, cz_.data(), cw_.data(), ctmp_.data());
  double rz = 0.0;
  for (int i = 0; i < m; ++i) rz += cz_[i] * cw_[i];
  scatter_cluster(cw_.data(), z);
  return rz;
}

// The cluster's part of the backward sweep: t_C = D_C^-1 p_C (it is last in the order), and
// its share A_jC t_C in the rows j it reaches; returns p_C . t_C. t_C is left in ct_, and 0
// in t for the rows' sweeps.
template <class T>
double PcgSolver::backward_cluster(const Bsr<T>& M, const double* p, double* t) {
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

// The cluster's part of the forward sweep, after the rows': u_C, A t_C and with kFresh r_C;
// t_C back in t (and r'_C in rb); returns p_C . u_C.
template <bool kFresh, class T>
double PcgSolver::forward_cluster(const Bsr<T>& M, const double* p, double* t, double* u, double* at, double* rb,
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

void PcgSolver::gather_cluster(const double* v, double* c) const {
  for (size_t a = 0; a < cluster_.size(); ++a)
    for (int k = 0; k < 3; ++k) c[3 * a + k] = v[3 * cluster_[a] + k];
}

void PcgSolver::scatter_cluster(const double* c, double* v) const {
  for (size_t a = 0; a < cluster_.size(); ++a)
    for (int k = 0; k < 3; ++k) v[3 * cluster_[a] + k] = c[3 * a + k];
}

// The preconditioner's dense block: the hub rows (proxies) with the nodes their non-zero
// blocks reach (the vertices in contact), at most kMaxCluster nodes, strongest coupling
// first. Block-Jacobi alone leaves a vertex's stiff contact to its proxy to the iterations,
// which then take many more (test_solver PcgWithContactHubsMatchesCholmod). Returns false if the
// block is not positive definite.
template <class T>
bool PcgSolver::factor_cluster(const Bsr<T>& M, const SymCsr& A) {
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
bool PcgSolver::cholesky(double* a, int m) {
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
void PcgSolver::cluster_from_copy(const Bsr<T>& M) {
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
void PcgSolver::cholesky_multiply(const double* l, int m, const double* x, double* y, double* tmp) {
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
void PcgSolver::cholesky_solve(const double* l, int m, double* y) {
  using Row = Eigen::Map<const Eigen::VectorXd>;
  for (int i = 0; i < m; ++i)
    y[i] = (y[i] - Row(l + i * m, i).dot(Row(y, i))) / l[i * m + i];
  for (int i = m - 1; i >= 0; --i) {
    y[i] /= l[i * m + i];
    Eigen::Map<Eigen::VectorXd>(y, i) -= y[i] * Row(l + i * m, i);
  }
}

// The float and double copies' instantiations, for the other files of the solver.
template void PcgSolver::settle_cluster<float>(const Bsr<float>& M, const double* b, double* x, double goal2);
template void PcgSolver::settle_cluster<double>(const Bsr<double>& M, const double* b, double* x, double goal2);
template void PcgSolver::cluster_to_touched<float>(const Bsr<float>& M, const double* vc);
template void PcgSolver::cluster_to_touched<double>(const Bsr<double>& M, const double* vc);
template double PcgSolver::backward_cluster<float>(const Bsr<float>& M, const double* p, double* t);
template double PcgSolver::backward_cluster<double>(const Bsr<double>& M, const double* p, double* t);
template double PcgSolver::forward_cluster<false, float>(const Bsr<float>& M, const double* p, double* t, double* u, double* at, double* rb,
                         const double* zb, double* r);
template double PcgSolver::forward_cluster<false, double>(const Bsr<double>& M, const double* p, double* t, double* u, double* at, double* rb,
                         const double* zb, double* r);
template double PcgSolver::forward_cluster<true, float>(const Bsr<float>& M, const double* p, double* t, double* u, double* at, double* rb,
                         const double* zb, double* r);
template double PcgSolver::forward_cluster<true, double>(const Bsr<double>& M, const double* p, double* t, double* u, double* at, double* rb,
                         const double* zb, double* r);
template bool PcgSolver::factor_cluster<float>(const Bsr<float>& M, const SymCsr& A);
template bool PcgSolver::factor_cluster<double>(const Bsr<double>& M, const SymCsr& A);
template void PcgSolver::cluster_from_copy<float>(const Bsr<float>& M);
template void PcgSolver::cluster_from_copy<double>(const Bsr<double>& M);

}  // namespace hapticloth::cloth::pcg
