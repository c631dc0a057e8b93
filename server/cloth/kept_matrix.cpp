#include "cloth/kept_matrix.hpp"

#include <cstddef>
#include <limits>

namespace hapticloth::cloth {

namespace {
using Mask = long long __attribute__((vector_size(8 * kLanes)));
inline Lanes vabs(Lanes a) { return a < Lanes{} ? -a : a; }
// The larger of a and b, and NaN if either is.
inline Lanes vmax(Lanes a, Lanes b) { return (a > b) | (a != a) ? a : b; }
}  // namespace

KeptMatrix::KeptMatrix(double tolerance, const std::vector<int>& group_counts, int block_rows)
    : tolerance_(tolerance), changed_(block_rows, 0), part_rows_(group_counts.size()) {
  for (auto& rows : part_rows_) rows.reserve(block_rows);  // a row is marked once: no allocation
  rows_.reserve(block_rows);
  if (enabled())
    for (int n : group_counts) kept_.emplace_back(n);
}

bool KeptMatrix::keeps(double h, double alpha, JacobianMode mode) const {
  return enabled() && valid_ && h == h_ && alpha == alpha_ && mode == mode_ && since_full_ < kFullEvery;
}

void KeptMatrix::assembled(double h, double alpha, JacobianMode mode, bool full) {
  valid_ = enabled();
  h_ = h;
  alpha_ = alpha;
  mode_ = mode;
  since_full_ = full ? 0 : since_full_ + 1;
}

void KeptMatrix::keep_factors(int part, int g, const ElementTerms& terms) {
  if (!enabled()) return;
  Factors& k = kept_[part][g];
  for (int i = 0; i < kFactors; ++i) k.f[i] = terms.factor[i];
}

unsigned KeptMatrix::take_changes(int part, int g, int count, ElementTerms& terms) {
  Factors& k = kept_[part][g];
  Lanes dmax{}, fmax{};
  for (int i = 0; i < kFactors; ++i) {
    dmax = vmax(dmax, vabs(terms.factor[i] - k.f[i]));
    fmax = vmax(fmax, vabs(terms.factor[i]));
  }
  // Held where the change is within the tolerance and the factors are finite: a NaN or an
  // infinity moves, and so reaches the solve, which fails the step.
  const Mask held = (dmax <= tolerance_ * fmax) & (fmax <= std::numeric_limits<double>::max());
  const Mask moved = ~held;
  unsigned lanes = 0;
  for (int l = 0; l < count; ++l) lanes |= moved[l] ? 1u << l : 0u;
  if (!lanes) return 0;
  for (int i = 0; i < kFactors; ++i) {
    const Lanes f = terms.factor[i];
    terms.factor[i] = moved ? f - k.f[i] : Lanes{};
    k.f[i] = moved ? f : k.f[i];
  }
  return lanes;
}

const std::vector<int>& KeptMatrix::take_changed_rows() {
  rows_.clear();
  for (auto& rows : part_rows_) {
    for (int r : rows) changed_[r] = 0;
    rows_.insert(rows_.end(), rows.begin(), rows.end());
    rows.clear();
  }
  return rows_;
}

}  // namespace hapticloth::cloth
