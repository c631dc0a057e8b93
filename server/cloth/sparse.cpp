#include "cloth/sparse.hpp"

#include <algorithm>

namespace hapticloth::cloth {

void SymCsr::multiply(const double* x, double* y) const {
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
