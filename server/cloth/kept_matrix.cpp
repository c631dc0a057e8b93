#include "cloth/kept_matrix.hpp"

#include <cstddef>
#include <limits>

namespace hapticloth::cloth {

KeptMatrix::KeptMatrix(double tolerance, int parts, int block_rows)
    : tolerance_(tolerance),
      changed_(block_rows, 0),
      part_rows_(parts, std::vector<int>(block_rows)),  // a row is marked once
      part_count_(parts, 0) {
  rows_.reserve(block_rows);
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

const std::vector<int>& KeptMatrix::take_changed_rows() {
  rows_.clear();
  for (std::size_t p = 0; p < part_rows_.size(); ++p) {
    const int* rows = part_rows_[p].data();
    for (int i = 0; i < part_count_[p]; ++i) changed_[rows[i]] = 0;
    rows_.insert(rows_.end(), rows, rows + part_count_[p]);
    part_count_[p] = 0;
  }
  return rows_;
}

}  // namespace hapticloth::cloth
