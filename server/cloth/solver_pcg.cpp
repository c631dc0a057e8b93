#include <Eigen/Dense>
#if defined(__AVX2__) && defined(__FMA__)
#include <immintrin.h>
#endif
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include "cloth/solver.hpp"

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

namespace {

// Block-sparse-row copy of a block3 SymCsr in two parts. The hub rows (block rows far longer
// than a mesh's: the fingertip proxies, coupled to every vertex) and their columns are kept
// apart, as the list of each hub row's non-zero blocks: a step uses the few blocks in contact
// of the proxies' dense rows and columns, so the product costs what the cloth alone costs. The
// rest, the cloth's blocks, has a fixed layout, so that one block row can be reloaded alone (a
// contact revision changes the rows of the vertices in contact and the hubs). Each 3x3 block's
// values are stored column-major with each column padded to 4 lanes, so that y += B x is three
// 4-wide multiply-adds of a column by a broadcast x entry. T = float halves the memory the
// product streams, which is what bounds PCG on large meshes (the product reads the whole matrix
// every iteration); products accumulate in double.
template <class T>
struct Bsr {
  static constexpr int kBlock = 12;  // 3 columns x 4 lanes

  std::vector<int> rowptr;  // per block row: first cloth block (hub rows have none)
  std::vector<int> xoff;    // per cloth block: scalar offset of its column triple in x
  std::vector<int> srck;    // per cloth block: its column position (in scalars) in A's row
  std::vector<int> diag;    // per block row: column position (in scalars) of its diagonal block in A's row
  std::vector<T> val;       // kBlock per cloth block
  std::vector<int> hubs;            // the hub block rows
  std::vector<char> is_hub;         // per block row
  std::vector<int> hub_ptr;         // per hub: first entry (hubs.size() + 1)
  std::vector<int> hub_col;         // per entry: the block column
  std::vector<T> hub_val;           // kBlock per entry

  void build_pattern(const SymCsr& A, const std::vector<int>& hub_rows) {
    const int nb = A.n / 3;
    hubs = hub_rows;
    is_hub.assign(nb, 0);
    for (int h : hubs) is_hub[h] = 1;
    rowptr.assign(nb + 1, 0);
    diag.assign(nb, -1);
    xoff.clear();
    srck.clear();
    int hub_blocks = 0;
    for (int br = 0; br < nb; ++br) {
      rowptr[br] = static_cast<int>(xoff.size());
      const int o = A.rowptr[3 * br], len = A.rowptr[3 * br + 1] - o;
      for (int k = 0; k < len; k += 3) {
        const int col = A.col[o + k];
        if (col == 3 * br) diag[br] = k;
        if (is_hub[br]) {
          ++hub_blocks;
        } else if (!is_hub[col / 3]) {
          xoff.push_back(col);
          srck.push_back(k);
        }
      }
      if (diag[br] < 0) throw std::invalid_argument("pcg: diagonal block missing from the pattern");
    }
    rowptr[nb] = static_cast<int>(xoff.size());
    val.assign(kBlock * xoff.size(), T(0));
    hub_ptr.assign(hubs.size() + 1, 0);
    hub_col.assign(hub_blocks, 0);
    hub_val.assign(kBlock * static_cast<std::size_t>(hub_blocks), T(0));
  }

  void load(const SymCsr& A) {
    const int nb = static_cast<int>(diag.size());
    for (int br = 0; br < nb; ++br) load_row(A, br);
    load_hubs(A);
  }

  // The cloth blocks of block row br (none for a hub row).
  void load_row(const SymCsr& A, int br) {
    const int o = A.rowptr[3 * br], len = A.rowptr[3 * br + 1] - o;
    const double* r0 = A.val.data() + o;
    T* dst = val.data() + kBlock * rowptr[br];
    for (int b = rowptr[br]; b < rowptr[br + 1]; ++b, dst += kBlock) store(r0 + srck[b], len, dst);
  }

  // Every hub row's blocks that are not exactly zero.
  void load_hubs(const SymCsr& A) {
    int e = 0;
    for (std::size_t i = 0; i < hubs.size(); ++i) {
      hub_ptr[i] = e;
      const int h = hubs[i], o = A.rowptr[3 * h], len = A.rowptr[3 * h + 1] - o;
      const double* r0 = A.val.data() + o;
      const double* r1 = r0 + len;
      const double* r2 = r1 + len;
      for (int k = 0; k < len; k += 3) {
        bool zero = true;
        for (int c = 0; c < 3; ++c) zero = zero && r0[k + c] == 0.0 && r1[k + c] == 0.0 && r2[k + c] == 0.0;
        if (zero && k != diag[h]) continue;
        hub_col[e] = A.col[o + k] / 3;
        store(r0 + k, len, hub_val.data() + kBlock * e);
        ++e;
      }
    }
    hub_ptr[hubs.size()] = e;
  }

  // The 3x3 block at p (rows `len` apart in A) into dst, column-major, padded.
  static void store(const double* p, int len, T* dst) {
    for (int c = 0; c < 3; ++c) {
      dst[4 * c] = T(p[c]);
      dst[4 * c + 1] = T(p[len + c]);
      dst[4 * c + 2] = T(p[2 * len + c]);
      dst[4 * c + 3] = T(0);
    }
  }

  // y = A x, and returns x . y (the PCG step needs p . Ap; fused to save a pass). y must have
  // one padding entry past its end (the last block row writes 4 lanes).
  double multiply_dot(const double* x, double* y) const {
    return multiply_cloth(x, y) + multiply_hubs(x, y);
  }

  // The cloth blocks: every block row's y (0 for a hub row), and x . y.
  double multiply_cloth(const double* x, double* y) const {
    const int nb = static_cast<int>(diag.size());
    const T* b = val.data();
#if defined(__AVX2__) && defined(__FMA__)
    __m256d dot = _mm256_setzero_pd();
    for (int br = 0; br < nb; ++br) {
      // Two accumulators: each block's product is an independent chain, only the sums chain.
      __m256d acc0 = _mm256_setzero_pd(), acc1 = _mm256_setzero_pd();
      const int kend = rowptr[br + 1];
      int k = rowptr[br];
      for (; k + 1 < kend; k += 2, b += 2 * kBlock) {
        const double* xa = x + xoff[k];
        const double* xb = x + xoff[k + 1];
        __m256d ta = _mm256_mul_pd(lanes(b), _mm256_broadcast_sd(xa));
        __m256d tb = _mm256_mul_pd(lanes(b + kBlock), _mm256_broadcast_sd(xb));
        ta = _mm256_fmadd_pd(lanes(b + 4), _mm256_broadcast_sd(xa + 1), ta);
        tb = _mm256_fmadd_pd(lanes(b + kBlock + 4), _mm256_broadcast_sd(xb + 1), tb);
        ta = _mm256_fmadd_pd(lanes(b + 8), _mm256_broadcast_sd(xa + 2), ta);
        tb = _mm256_fmadd_pd(lanes(b + kBlock + 8), _mm256_broadcast_sd(xb + 2), tb);
        acc0 = _mm256_add_pd(acc0, ta);
        acc1 = _mm256_add_pd(acc1, tb);
      }
      if (k < kend) {
        const double* xa = x + xoff[k];
        __m256d ta = _mm256_mul_pd(lanes(b), _mm256_broadcast_sd(xa));
        ta = _mm256_fmadd_pd(lanes(b + 4), _mm256_broadcast_sd(xa + 1), ta);
        ta = _mm256_fmadd_pd(lanes(b + 8), _mm256_broadcast_sd(xa + 2), ta);
        acc0 = _mm256_add_pd(acc0, ta);
        b += kBlock;
      }
      const __m256d yv = _mm256_add_pd(acc0, acc1);  // lane 3 is 0 (padding)
      _mm256_storeu_pd(y + 3 * br, yv);
      // x's lane 3 belongs to the next row; the padded lane of yv is 0, so it adds nothing.
      dot = _mm256_fmadd_pd(_mm256_loadu_pd(x + 3 * br), yv, dot);
    }
    alignas(32) double d[4];
    _mm256_store_pd(d, dot);
    return (d[0] + d[1]) + (d[2] + d[3]);
#else
    double dot = 0.0;
    for (int br = 0; br < nb; ++br) {
      double s0 = 0.0, s1 = 0.0, s2 = 0.0;
      for (int k = rowptr[br]; k < rowptr[br + 1]; ++k, b += kBlock) {
        const double* xc = x + xoff[k];
        for (int c = 0; c < 3; ++c) {
          s0 += double(b[4 * c]) * xc[c];
          s1 += double(b[4 * c + 1]) * xc[c];
          s2 += double(b[4 * c + 2]) * xc[c];
        }
      }
      y[3 * br] = s0;
      y[3 * br + 1] = s1;
      y[3 * br + 2] = s2;
      dot += x[3 * br] * s0 + x[3 * br + 1] * s1 + x[3 * br + 2] * s2;
    }
    return dot;
#endif
  }

  // The hub blocks, after multiply_cloth: y_h = sum_j B_hj x_j for each hub h, and for a cloth
  // column j the symmetric block's share y_j += B_hj^T x_h; returns what they add to x . y.
  double multiply_hubs(const double* x, double* y) const {
    double dot = 0.0;
    for (std::size_t i = 0; i < hubs.size(); ++i) {
      const int h = hubs[i];
      const double* xh = x + 3 * h;
      double yh0 = 0.0, yh1 = 0.0, yh2 = 0.0;
      for (int e = hub_ptr[i]; e < hub_ptr[i + 1]; ++e) {
        const T* B = hub_val.data() + kBlock * e;  // B(r, c) = B[4 c + r]
        const int j = hub_col[e];
        const double* xj = x + 3 * j;
        yh0 += double(B[0]) * xj[0] + double(B[4]) * xj[1] + double(B[8]) * xj[2];
        yh1 += double(B[1]) * xj[0] + double(B[5]) * xj[1] + double(B[9]) * xj[2];
        yh2 += double(B[2]) * xj[0] + double(B[6]) * xj[1] + double(B[10]) * xj[2];
        if (is_hub[j]) continue;  // a hub's own row lists its block
        const double d0 = double(B[0]) * xh[0] + double(B[1]) * xh[1] + double(B[2]) * xh[2];
        const double d1 = double(B[4]) * xh[0] + double(B[5]) * xh[1] + double(B[6]) * xh[2];
        const double d2 = double(B[8]) * xh[0] + double(B[9]) * xh[1] + double(B[10]) * xh[2];
        y[3 * j] += d0;
        y[3 * j + 1] += d1;
        y[3 * j + 2] += d2;
        dot += xj[0] * d0 + xj[1] * d1 + xj[2] * d2;
      }
      y[3 * h] = yh0;
      y[3 * h + 1] = yh1;
      y[3 * h + 2] = yh2;
      dot += xh[0] * yh0 + xh[1] * yh1 + xh[2] * yh2;
    }
    return dot;
  }

 private:
#if defined(__AVX2__) && defined(__FMA__)
  static __m256d lanes(const double* p) { return _mm256_loadu_pd(p); }
  static __m256d lanes(const float* p) { return _mm256_cvtps_pd(_mm_loadu_ps(p)); }
#endif
};

class PcgSolver final : public LinearSolver {
 public:
  explicit PcgSolver(const PcgOptions& o) : opt_(o) {
    if (!(o.tolerance > 0.0) || !std::isfinite(o.tolerance) || o.max_iterations < 1)
      throw std::invalid_argument("pcg: tolerance must be > 0 and max_iterations >= 1");
  }
  const char* name() const override { return "pcg"; }

  void analyze(const SymCsr& A) override {
    if (A.n % 3 != 0) throw std::invalid_argument("pcg: matrix size must be a multiple of 3");
    if (!A.block3) throw std::invalid_argument("pcg: the matrix must have 3x3 block structure");
    n_ = A.n;
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
    if (opt_.single_precision_matrix) mf_.build_pattern(A, hub_rows);
    md_.build_pattern(A, hub_rows);  // also the fallback of the float copy
    hubs_ = opt_.hub_block ? hub_rows : std::vector<int>{};
    local_.assign(nb, -1);
    cluster_.clear();
    cluster_.reserve(kMaxCluster);
    weight_.clear();
    weight_.reserve(nb);
  }

  // With the float copy, a system too ill-conditioned for its rounding (the residual stalls
  // above the tolerance: a 1000x stiffer cloth at a 20 ms step in hapticloth-bench stability)
  // is solved again with the double copy (its iterations are the ones reported).
  SolveStatus solve(const SymCsr& A, const double* b, double* x) override {
    float_in_use_ = opt_.single_precision_matrix;
    if (!float_in_use_) return run(md_, A, b, x, true);
    std::copy(x, x + n_, guess_.begin());
    const SolveStatus st = run(mf_, A, b, x, true);
    if (st != SolveStatus::NotConverged) return st;
    float_in_use_ = false;
    std::copy(guess_.begin(), guess_.begin() + n_, x);
    return run(md_, A, b, x, true);
  }
  // The matrix copy and the preconditioner of the last solve serve again.
  SolveStatus resolve(const SymCsr& A, const double* b, double* x) override {
    if (!prepared_) return solve(A, b, x);
    return float_in_use_ ? run(mf_, A, b, x, false) : run(md_, A, b, x, false);
  }
  // The copy in use (the one the last solve prepared) gets the changed rows; the float one
  // falls back to a whole double solve as solve() does.
  SolveStatus solve_changed(const SymCsr& A, const int* block_rows, int count, const double* b,
                            double* x) override {
    if (!prepared_) return solve(A, b, x);
    if (!float_in_use_) return run_changed(md_, A, block_rows, count, b, x);
    std::copy(x, x + n_, guess_.begin());
    const SolveStatus st = run_changed(mf_, A, block_rows, count, b, x);
    if (st != SolveStatus::NotConverged) return st;
    float_in_use_ = false;
    std::copy(guess_.begin(), guess_.begin() + n_, x);
    return run(md_, A, b, x, true);
  }

 private:
  template <class T>
  SolveStatus run(Bsr<T>& M, const SymCsr& A, const double* b, double* x, bool load) {
    iterations_ = 0;
    residual_ = 0.0;
    const int n = n_, nb = n_ / 3;
    if (load && !prepare(M, A)) return SolveStatus::NotPositiveDefinite;
    return iterate(M, b, x, n, nb);
  }

  // A re-solve after a change in a few block rows: those rows reloaded and re-preconditioned,
  // the hubs' blocks reloaded and their dense block factored again. A contact revision of the
  // pinched 968-triangle square then reloads some tens of rows of the matrix, not all of it.
  template <class T>
  SolveStatus run_changed(Bsr<T>& M, const SymCsr& A, const int* rows, int count, const double* b,
                          double* x) {
    iterations_ = 0;
    residual_ = 0.0;
    prepared_ = false;
    for (int i = 0; i < count; ++i) {
      M.load_row(A, rows[i]);
      if (!invert_diagonal(A, rows[i], M.diag[rows[i]])) return SolveStatus::NotPositiveDefinite;
    }
    M.load_hubs(A);
    if (!hubs_.empty() && !factor_cluster(M, A)) return SolveStatus::NotPositiveDefinite;
    prepared_ = true;
    return iterate(M, b, x, n_, n_ / 3);
  }

  // The matrix copy, the block-Jacobi inverses and the hub block. False if a diagonal block or
  // the hub block is not positive definite.
  template <class T>
  bool prepare(Bsr<T>& M, const SymCsr& A) {
    prepared_ = false;
    const int nb = n_ / 3;
    M.load(A);
    for (int br = 0; br < nb; ++br)
      if (!invert_diagonal(A, br, M.diag[br])) return false;
    if (!hubs_.empty() && !factor_cluster(M, A)) return false;
    prepared_ = true;
    return true;
  }

  // Block-Jacobi preconditioner: the inverse of block row br's 3x3 diagonal block (at column
  // position d of A's row; from the double values, by cofactors). False if it is not positive
  // definite.
  bool invert_diagonal(const SymCsr& A, int br, int d) {
    const int o = A.rowptr[3 * br], len = A.rowptr[3 * br + 1] - o;
    const double* r0 = A.val.data() + o + d;
    const double a00 = r0[0], a01 = r0[1], a02 = r0[2];
    const double a10 = r0[len], a11 = r0[len + 1], a12 = r0[len + 2];
    const double a20 = r0[2 * len], a21 = r0[2 * len + 1], a22 = r0[2 * len + 2];
    const double c00 = a11 * a22 - a12 * a21, c01 = a02 * a21 - a01 * a22, c02 = a01 * a12 - a02 * a11;
    const double det = a00 * c00 + a10 * c01 + a20 * c02;
    if (!(det > 0.0) || !std::isfinite(det) || !(a00 > 0.0)) return false;
    const double id = 1.0 / det;
    double* m = inv_.data() + 9 * br;
    m[0] = c00 * id;
    m[1] = c01 * id;
    m[2] = c02 * id;
    m[3] = (a12 * a20 - a10 * a22) * id;
    m[4] = (a00 * a22 - a02 * a20) * id;
    m[5] = (a02 * a10 - a00 * a12) * id;
    m[6] = (a10 * a21 - a11 * a20) * id;
    m[7] = (a01 * a20 - a00 * a21) * id;
    m[8] = (a00 * a11 - a01 * a10) * id;
    return true;
  }

  // Preconditioned conjugate gradients from the guess in x, until |r| <= tolerance |b|.
  template <class T>
  SolveStatus iterate(const Bsr<T>& M, const double* b, double* x, int n, int nb) {
    double bn2 = 0.0;
    for (int i = 0; i < n; ++i) bn2 += b[i] * b[i];
    if (!std::isfinite(bn2)) return SolveStatus::NumericalError;
    if (bn2 == 0.0) {
      std::fill(x, x + n, 0.0);
      return SolveStatus::Ok;
    }
    const double bnorm = std::sqrt(bn2);
    bool finite = true;
    for (int i = 0; i < n; ++i) finite = finite && std::isfinite(x[i]);
    if (!finite) std::fill(x, x + n, 0.0);
    double* r = r_.data();
    double* z = z_.data();
    double* p = p_.data();
    double* q = q_.data();
    std::copy(x, x + n, x0_.data());  // padded copy of the guess for the product
    M.multiply_dot(x0_.data(), q);
    for (int i = 0; i < n; ++i) r[i] = b[i] - q[i];
    const double goal2 = opt_.tolerance * opt_.tolerance * bn2;
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

  // The preconditioner's dense block: the hub rows (proxies) with the nodes their non-zero
  // blocks reach (the vertices in contact), at most kMaxCluster nodes, strongest coupling
  // first. Block-Jacobi alone leaves a vertex's stiff contact to its proxy to the iterations:
  // on the pinched 968-triangle square that doubled them. Returns false if the block is not
  // positive definite.
  template <class T>
  bool factor_cluster(const Bsr<T>& M, const SymCsr& A) {
    for (int node : cluster_) local_[node] = -1;
    cluster_.clear();
    weight_.clear();
    for (std::size_t i = 0; i < M.hubs.size(); ++i)
      for (int k = M.hub_ptr[i]; k < M.hub_ptr[i + 1]; ++k) {
        const int hub = M.hubs[i], node = M.hub_col[k];
        const T* blk = M.hub_val.data() + Bsr<T>::kBlock * k;
        const double w = std::abs(double(blk[0])) + std::abs(double(blk[5])) + std::abs(double(blk[10]));
        if (node != hub) weight_.push_back({-w, node});
      }
    for (int hub : hubs_) weight_.push_back({-std::numeric_limits<double>::infinity(), hub});
    std::sort(weight_.begin(), weight_.end());
    for (const auto& [w, node] : weight_) {
      if (static_cast<int>(cluster_.size()) == kMaxCluster) break;
      if (local_[node] >= 0) continue;
      local_[node] = static_cast<int>(cluster_.size());
      cluster_.push_back(node);
    }
    const int m = 3 * static_cast<int>(cluster_.size());
    std::fill(dense_.begin(), dense_.begin() + m * m, 0.0);
    for (int a : cluster_) {
      const int o = A.rowptr[3 * a], len = A.rowptr[3 * a + 1] - o;
      for (int k = 0; k < len; k += 3) {
        const int b = local_[A.col[o + k] / 3];
        if (b < 0) continue;
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) dense_[(3 * local_[a] + r) * m + 3 * b + c] = A.val[o + r * len + k + c];
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
  std::vector<int> hubs_, local_, cluster_;
  std::vector<std::pair<double, int>> weight_;
  std::array<double, 9 * kMaxCluster * kMaxCluster> dense_{};
  std::array<double, 3 * kMaxCluster> cz_{};

  PcgOptions opt_;
  bool prepared_ = false, float_in_use_ = false;
  std::vector<double> guess_;  // the starting guess, for the double solve after a float one
  int n_ = 0;
  std::vector<double> r_, z_, p_, q_, x0_, inv_;
  Bsr<double> md_;
  Bsr<float> mf_;
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
