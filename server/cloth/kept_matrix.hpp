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

#include <cstring>
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

/// The two ways an assembly forms eq. 9's matrix, as the tags it is run with (KeptMatrix::keeps
/// chooses per step). WholeMatrix: the values cleared, then every term added.
struct WholeMatrix {
  /// Values [begin, end) cleared before the terms go in.
  static void clear(double* values, int begin, int end) {
    std::memset(values + begin, 0, sizeof(double) * static_cast<std::size_t>(end - begin));
  }
  /// A term that is the same every step (the lumped mass, the air damping): added.
  static void add_steady(double& entry, double value) { entry += value; }
  /// Whether the matrix holds an external stiffness from before (it holds nothing).
  static bool holds_stiffness(bool /*held*/) { return false; }
  /// Rows whose terms changed need no mark: the solver loads the whole matrix.
  static void mark(KeptMatrix&, int /*part*/, int /*row*/) {}
};

/// KeptChanges: the matrix in hand kept; only the terms that moved are added, as their change,
/// and their rows marked for the solver to reload.
struct KeptChanges {
  static void clear(double*, int, int) {}
  static void add_steady(double&, double) {}
  static bool holds_stiffness(bool held) { return held; }
  static void mark(KeptMatrix& kept, int part, int row) { kept.mark(part, row); }
};

}  // namespace hapticloth::cloth
