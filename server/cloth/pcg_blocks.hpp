// The PCG's block-sparse copy of the system matrix (Bsr) and the 4-lane arithmetic on its 3x3
// blocks that the product and the Gauss-Seidel sweeps share. Internal to the PCG solver (pcg_solver.hpp).
#pragma once

#if defined(__AVX__)
#include <immintrin.h>
#endif
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <vector>

#include "cloth/sparse.hpp"

namespace hapticloth::cloth::pcg {

// m = a^-1 by cofactors; false unless a is positive definite enough to pass det > 0, a00 > 0.
inline __attribute__((always_inline)) bool inverse3(const double a[3][3], double m[3][3]) {
  const double c00 = a[1][1] * a[2][2] - a[1][2] * a[2][1];
  const double c01 = a[0][2] * a[2][1] - a[0][1] * a[2][2];
  const double c02 = a[0][1] * a[1][2] - a[0][2] * a[1][1];
  const double det = a[0][0] * c00 + a[1][0] * c01 + a[2][0] * c02;
  if (!(det > 0.0) || !std::isfinite(det) || !(a[0][0] > 0.0)) return false;
  const double id = 1.0 / det;
  m[0][0] = c00 * id;
  m[0][1] = c01 * id;
  m[0][2] = c02 * id;
  m[1][0] = (a[1][2] * a[2][0] - a[1][0] * a[2][2]) * id;
  m[1][1] = (a[0][0] * a[2][2] - a[0][2] * a[2][0]) * id;
  m[1][2] = (a[0][2] * a[1][0] - a[0][0] * a[1][2]) * id;
  m[2][0] = (a[1][0] * a[2][1] - a[1][1] * a[2][0]) * id;
  m[2][1] = (a[0][1] * a[2][0] - a[0][0] * a[2][1]) * id;
  m[2][2] = (a[0][0] * a[1][1] - a[0][1] * a[1][0]) * id;
  return true;
}

// Scalar products with a 3x3 block B stored column-major with 4-lane columns, B(r, c) = B[4c + r]:
// s += B x, s -= B x, s += B^T x (the few blocks of the fingertips' rows).
template <bool Transposed, class T>
double block_row_times(const T* B, int r, const double* x) {
  constexpr int kRow = Transposed ? 4 : 1, kColumn = Transposed ? 1 : 4;  // strides of (r, c)
  return double(B[kRow * r]) * x[0] + double(B[kRow * r + kColumn]) * x[1] +
         double(B[kRow * r + 2 * kColumn]) * x[2];
}
template <class T>
void add_block(const T* B, const double* x, double* s) {
  for (int r = 0; r < 3; ++r) s[r] += block_row_times<false>(B, r, x);
}
template <class T>
void sub_block(const T* B, const double* x, double* s) {
  for (int r = 0; r < 3; ++r) s[r] -= block_row_times<false>(B, r, x);
}
template <class T>
void add_block_t(const T* B, const double* x, double* s) {
  for (int r = 0; r < 3; ++r) s[r] += block_row_times<true>(B, r, x);
}

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
  std::vector<double> dinv;  // per cloth block row, with_dinv: its diagonal block's inverse, column-major, padded
  bool with_dinv = false;
  double dinv_scale = 1.0;  // omega: SSOR's sweeps divide by D / omega
  std::vector<int> diag;    // per block row: column position (in scalars) of its diagonal block in A's row
  std::vector<int> dblk;    // per cloth block row: index of its diagonal block (lower blocks before, upper after)
  std::vector<T> val;       // kBlock per cloth block
  std::vector<int> hubs;            // the hub block rows
  std::vector<char> is_hub;         // per block row
  std::vector<int> hub_ptr;         // per hub: first entry (hubs.size() + 1)
  std::vector<int> hub_col;         // per entry: the block column
  std::vector<T> hub_val;           // kBlock per entry
  std::vector<int> next_ptr, next_col;  // reload_hubs' new lists, swapped in (sized as the above)
  std::vector<T> next_val;

  // rank: each block row's place in the order of the Gauss-Seidel sweeps; a cloth row's blocks
  // are kept in that order, so the ones before its diagonal block (dblk) are its lower part.
  void build_pattern(const SymCsr& A, const std::vector<int>& hub_rows, const std::vector<int>& rank) {
    const int nb = A.n / 3;
    hubs = hub_rows;
    is_hub.assign(nb, 0);
    for (int h : hubs) is_hub[h] = 1;
    rowptr.assign(nb + 1, 0);
    diag.assign(nb, -1);
    dblk.assign(nb, -1);
    xoff.clear();
    srck.clear();
    int hub_blocks = 0;
    std::vector<std::array<int, 3>> row;  // rank, column, position
    for (int br = 0; br < nb; ++br) {
      rowptr[br] = static_cast<int>(xoff.size());
      const int o = A.rowptr[3 * br], len = A.rowptr[3 * br + 1] - o;
      row.clear();
      for (int k = 0; k < len; k += 3) {
        const int col = A.col[o + k];
        if (col == 3 * br) diag[br] = k;
        if (is_hub[br])
          ++hub_blocks;
        else if (!is_hub[col / 3])
          row.push_back({rank[col / 3], col, k});
      }
      if (diag[br] < 0) throw std::invalid_argument("pcg: diagonal block missing from the pattern");
      std::sort(row.begin(), row.end());
      for (const auto& [rk, col, k] : row) {
        if (col == 3 * br) dblk[br] = static_cast<int>(xoff.size());
        xoff.push_back(col);
        srck.push_back(k);
      }
    }
    rowptr[nb] = static_cast<int>(xoff.size());
    val.assign(kBlock * xoff.size(), T(0));
    dinv.assign(with_dinv ? 12 * static_cast<size_t>(nb) : 0, 0.0);
    hub_ptr.assign(hubs.size() + 1, 0);
    hub_col.assign(hub_blocks, 0);
    hub_val.assign(kBlock * static_cast<std::size_t>(hub_blocks), T(0));
    next_ptr = hub_ptr;
    next_col = hub_col;
    next_val = hub_val;
  }

  // Block rows [lo, hi) (load_row), without the hubs (load_hubs): rows apart write apart, so
  // two threads may take two ranges. False if a diagonal block is not positive definite.
  bool load_rows(const SymCsr& A, int lo, int hi) {
    bool pd = true;
    for (int br = lo; br < hi; ++br) pd = load_row(A, br) && pd;
    return pd;
  }

  // The cloth blocks of block row br (none for a hub row), and with_dinv its diagonal block's
  // inverse, from the stored (rounded) values while they are at hand. False if that block is
  // not positive definite.
  bool load_row(const SymCsr& A, int br) {
    const int o = A.rowptr[3 * br], len = A.rowptr[3 * br + 1] - o;
    const double* r0 = A.val.data() + o;
    T* dst = val.data() + kBlock * rowptr[br];
    for (int b = rowptr[br]; b < rowptr[br + 1]; ++b, dst += kBlock) store(r0 + srck[b], len, dst);
    if (!with_dinv || dblk[br] < 0) return true;
    const T* B = val.data() + kBlock * dblk[br];
    double a[3][3], m[3][3];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) a[r][c] = double(B[4 * c + r]);
    if (!inverse3(a, m)) return false;
    double* mc = dinv.data() + 12 * br;
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 4; ++r) mc[4 * c + r] = r < 3 ? dinv_scale * m[r][c] : 0.0;
    return true;
  }

  // Every hub row's blocks that are not exactly zero, in column order.
  void load_hubs(const SymCsr& A) {
    int e = 0;
    for (std::size_t i = 0; i < hubs.size(); ++i) {
      hub_ptr[i] = e;
      const int h = hubs[i], o = A.rowptr[3 * h], len = A.rowptr[3 * h + 1] - o;
      for (int k = 0; k < len; k += 3)
        if (take_hub_block(A, h, o, len, k, hub_col.data() + e, hub_val.data() + kBlock * e)) ++e;
    }
    hub_ptr[hubs.size()] = e;
  }

  // The hub rows' blocks after a change of A in the block rows `sorted` (ascending; `listed`:
  // per block row, nonzero if it is one of them) and, by symmetry, in their columns. A hub row's
  // block at a column not listed is the transpose of that row's block, which did not change, so
  // it is kept; only the listed columns are read from A (a kept matrix's step, or a contact
  // revision, changes a few tens of them where load_hubs scans the hubs' whole rows). The same
  // lists as load_hubs would make.
  void reload_hubs(const SymCsr& A, const int* sorted, int count, const std::vector<char>& listed) {
    int e = 0;
    for (std::size_t i = 0; i < hubs.size(); ++i) {
      next_ptr[i] = e;
      const int h = hubs[i], o = A.rowptr[3 * h], len = A.rowptr[3 * h + 1] - o;
      int old = hub_ptr[i], j = 0;
      const int old_end = hub_ptr[i + 1];
      while (old < old_end || j < count) {
        if (old < old_end && listed[hub_col[old]]) {  // read afresh below, if still there
          ++old;
          continue;
        }
        if (j == count || (old < old_end && hub_col[old] < sorted[j])) {  // kept as it was
          next_col[e] = hub_col[old];
          std::copy_n(hub_val.data() + kBlock * old, kBlock, next_val.data() + kBlock * e);
          ++e;
          ++old;
          continue;
        }
        const int k = A.find(3 * h, 3 * sorted[j++]);
        if (k >= 0 && take_hub_block(A, h, o, len, k - o, next_col.data() + e, next_val.data() + kBlock * e)) ++e;
      }
    }
    next_ptr[hubs.size()] = e;
    hub_ptr.swap(next_ptr);
    hub_col.swap(next_col);
    hub_val.swap(next_val);
  }

  // Hub row h's block at column position k of its row in A (which starts at o, `len` long)
  // into *col and dst, unless it is exactly zero and not the diagonal block.
  bool take_hub_block(const SymCsr& A, int h, int o, int len, int k, int* col, T* dst) const {
    const double* r0 = A.val.data() + o;
    bool zero = true;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) zero = zero && r0[r * len + k + c] == 0.0;
    if (zero && k != diag[h]) return false;
    *col = A.col[o + k] / 3;
    store(r0 + k, len, dst);
    return true;
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
      double yh[3] = {0.0, 0.0, 0.0};
      for (int e = hub_ptr[i]; e < hub_ptr[i + 1]; ++e) {
        const T* B = hub_val.data() + kBlock * e;
        const int j = hub_col[e];
        const double* xj = x + 3 * j;
        add_block(B, xj, yh);
        if (is_hub[j]) continue;  // a hub's own row lists its block
        double d[3] = {0.0, 0.0, 0.0};
        add_block_t(B, xh, d);
        for (int c = 0; c < 3; ++c) y[3 * j + c] += d[c];
        dot += xj[0] * d[0] + xj[1] * d[1] + xj[2] * d[2];
      }
      for (int c = 0; c < 3; ++c) y[3 * h + c] = yh[c];
      dot += xh[0] * yh[0] + xh[1] * yh[1] + xh[2] * yh[2];
    }
    return dot;
  }

 private:
#if defined(__AVX2__) && defined(__FMA__)
  static __m256d lanes(const double* p) { return _mm256_loadu_pd(p); }
  static __m256d lanes(const float* p) { return _mm256_cvtps_pd(_mm_loadu_ps(p)); }
#endif
};

// Four double lanes (GCC's vector extension: AVX on x86-64 with it, pairs of SSE2 without), for
// the Gauss-Seidel sweeps: a 3-vector is lanes 0-2, a 3x3 block three padded columns.
using V4 = double __attribute__((vector_size(32)));
using F4 = float __attribute__((vector_size(16)));
inline V4 column(const double* c) {
  V4 v;
  std::memcpy(&v, c, sizeof v);
  return v;
}
inline V4 column(const float* c) {
#if defined(__AVX__)
  return _mm256_cvtps_pd(_mm_loadu_ps(c));
#else
  F4 f;
  std::memcpy(&f, c, sizeof f);
  return __builtin_convertvector(f, V4);
#endif
}
inline V4 splat(double x) { return V4{x, x, x, x}; }
// Lanes 0-2 are v[0..2]; lane 3 is whatever follows (v must have one entry past its end, which
// no other thread may be writing: there, load3).
inline V4 load4(const double* v) { return column(v); }
// Lanes 0-2 are v[0..2], lane 3 is 0: a row whose next entry may be the other part's, written
// by the other thread at the same time.
inline V4 load3(const double* v) { return V4{v[0], v[1], v[2], 0.0}; }
// Stores lanes 0-2 only: the entry after them may be another row's, already computed.
inline void store3(double* v, V4 a) {
  v[0] = a[0];
  v[1] = a[1];
  v[2] = a[2];
}
// B x for a column-major padded 3x3 block (lane 3 is 0).
template <class T>
inline V4 block_times(const T* B, const double* x) {
  return column(B) * splat(x[0]) + column(B + 4) * splat(x[1]) + column(B + 8) * splat(x[2]);
}
inline V4 block_times(const double* B, V4 x) {
  return column(B) * splat(x[0]) + column(B + 4) * splat(x[1]) + column(B + 8) * splat(x[2]);
}
inline double sum3(V4 a) { return a[0] + a[1] + a[2]; }

}  // namespace hapticloth::cloth::pcg
