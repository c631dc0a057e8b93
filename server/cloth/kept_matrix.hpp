// The system matrix of eq. 9 kept from step to step, each element's blocks formed anew only
// when its factored Jacobian has moved (IntegratorConfig::matrix_refresh).
//
// Why: a cloth at rest, or held still in a pinch, changes its Jacobian by a few parts in a
// million a step, yet forming the matrix anew scatters every element's nine blocks into their
// rows and the PCG then copies every row: a large share of a pinch's step (docs/performance.md,
// 'The kept matrix'). Kept, a step adds the blocks of the factors' difference (the
// blocks are linear in the factors: element_lanes.hpp, kFactors) for the elements that moved,
// and the solver reloads the rows they reach (LinearSolver::solve_changed). The forces, the
// right-hand side h (F - alpha h H v) and the energies stay exact every step; only the matrix of
// the linearly implicit step is within matrix_refresh of the current one per element, which a
// linearly implicit Euler step allows (an approximate Jacobian keeps it consistent: a
// W-method, Hairer and Wanner, Solving ODEs II, IV.7).
#pragma once

#include <vector>

#include "cloth/element.hpp"

namespace hapticloth::cloth {

class KeptMatrix {
 public:
  /// Assemblies between two formed whole: bounds the rounding that the kept sums gather.
  static constexpr int kFullEvery = 1000;

  /// `parts`: the assembly parts (the last: the elements the calling thread runs alone);
  /// `block_rows`: the system's block rows. The factors themselves are the element pass's
  /// (ElementPass::run), in its lanes.
  KeptMatrix(double tolerance, int parts, int block_rows);

  bool enabled() const { return tolerance_ > 0.0; }
  /// An element's blocks are formed anew when its factors moved by more than this fraction of
  /// their largest entry.
  double tolerance() const { return tolerance_; }
  /// Whether the matrix in hand may be kept for a step h at alpha in `mode`: it was formed for
  /// the same three, and not too long ago.
  bool keeps(double h, double alpha, JacobianMode mode) const;
  /// The matrix has been formed whole (full) or kept for (h, alpha, mode).
  void assembled(double h, double alpha, JacobianMode mode, bool full);
  /// The matrix in hand no longer holds the kept sums (a failed assembly).
  void invalidate() { valid_ = false; }

  /// Block row `row` changed in this assembly; a part's thread marks only its own rows. (A
  /// fixed array and a count, not push_back: the element pass of every instruction level calls
  /// it, and no library code may be compiled inside a level's translation unit.)
  void mark(int part, int row) {
    if (changed_[row]) return;
    changed_[row] = 1;
    part_rows_[part][part_count_[part]++] = row;
  }
  /// The rows marked since the last call, each once, and the marks cleared.
  const std::vector<int>& take_changed_rows();

 private:
  double tolerance_;
  std::vector<char> changed_;               // per block row
  std::vector<std::vector<int>> part_rows_;  // per part: block_rows entries, part_count_ used
  std::vector<int> part_count_;
  std::vector<int> rows_;
  bool valid_ = false;
  double h_ = 0.0, alpha_ = 0.0;
  JacobianMode mode_ = JacobianMode::Spd;
  int since_full_ = 0;
};

}  // namespace hapticloth::cloth
