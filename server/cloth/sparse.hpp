// Compressed sparse row storage of a symmetric matrix, both triangles stored.
#pragma once

#include <vector>

namespace hapticloth::cloth {

/// Symmetric matrix in CSR with sorted columns and both triangles present. Because it is
/// symmetric, the same arrays are also its compressed-sparse-column form (what CHOLMOD reads).
struct SymCsr {
  int n = 0;
  std::vector<int> rowptr;  ///< n + 1 entries
  std::vector<int> col;     ///< nnz entries, sorted within each row
  std::vector<double> val;  ///< nnz entries

  /// True if rows come in triples (3i, 3i+1, 3i+2) with identical column lists made of whole
  /// 3-column blocks: the 3x3 block structure of a vertex system. Enables the blocked product.
  bool block3 = false;

  int nnz() const { return static_cast<int>(col.size()); }
  /// y = A x (allocation-free).
  void multiply(const double* x, double* y) const;
  /// Offset of entry (r, c), or -1. O(log row length).
  int find(int r, int c) const;
};

}  // namespace hapticloth::cloth
