#include "cloth/sparse.hpp"

#include <algorithm>

namespace hapticloth::cloth {

void SymCsr::multiply(const double* x, double* y) const {
  if (block3) {
    // One column index per 3x3 block; the block's three rows sit `len` entries apart.
    const int* rp = rowptr.data();
    const int* ci = col.data();
    const double* v = val.data();
    for (int r = 0; r < n; r += 3) {
      const int o = rp[r], len = rp[r + 1] - o;
      const double* r0 = v + o;
      const double* r1 = r0 + len;
      const double* r2 = r1 + len;
      double s0 = 0.0, s1 = 0.0, s2 = 0.0;
      for (int k = 0; k < len; k += 3) {
        const double* xc = x + ci[o + k];
        const double x0 = xc[0], x1 = xc[1], x2 = xc[2];
        s0 += r0[k] * x0 + r0[k + 1] * x1 + r0[k + 2] * x2;
        s1 += r1[k] * x0 + r1[k + 1] * x1 + r1[k + 2] * x2;
        s2 += r2[k] * x0 + r2[k + 1] * x1 + r2[k + 2] * x2;
      }
      y[r] = s0;
      y[r + 1] = s1;
      y[r + 2] = s2;
    }
    return;
  }
  const int* rp = rowptr.data();
  const int* ci = col.data();
  const double* v = val.data();
  for (int r = 0; r < n; ++r) {
    double s = 0.0;
    for (int k = rp[r]; k < rp[r + 1]; ++k) s += v[k] * x[ci[k]];
    y[r] = s;
  }
}

int SymCsr::find(int r, int c) const {
  const auto b = col.begin() + rowptr[r], e = col.begin() + rowptr[r + 1];
  const auto it = std::lower_bound(b, e, c);
  return (it != e && *it == c) ? static_cast<int>(it - col.begin()) : -1;
}

}  // namespace hapticloth::cloth
