// The element pass of eq. 9 at one instruction level: for every element, eqs. 3-7 and its terms
// of the linear system, scattered into the matrix rows and right-hand sides of its free corners.
//
// Each level (simd_level.hpp) is its own translation unit built from element_lanes.hpp with its
// lane width and -march; ElementKernels is its table of entry points. The integrator takes the
// table of the level it runs at and owns one ElementPass from it.
#pragma once

#include <array>
#include <memory>
#include <vector>

#include "cloth/element.hpp"
#include "cloth/material.hpp"
#include "cloth/simd_level.hpp"

namespace hapticloth::cloth {

class KeptMatrix;
struct WholeMatrix;
struct KeptChanges;

struct StepFactors {
  double h;       ///< the (sub)step, s
  double alpha;   ///< implicitness (eq. 8)
};

/// The factored system Jacobian of an element, alpha^2 h^2 (P, Q, W) + alpha h (Pc, Qc, Wc):
/// the symmetric P and Q by their upper entries (00, 01, 02, 11, 12, 22), then W whole,
/// column-major. Every system block is linear in these, which is what lets a kept matrix take an
/// element's change as the blocks of its factors' difference (KeptMatrix).
inline constexpr int kFactors = 21;
inline constexpr int kFactorP = 0, kFactorQ = 6, kFactorW = 12;
/// Block (k, l), k <= l, of an element's 3 x 3 blocks; (l, k) is its transpose.
inline constexpr int kPair[3][3] = {{0, 1, 2}, {1, 3, 4}, {2, 4, 5}};

/// One element's terms of eq. 9 as the lanes compute them: the right-hand side
/// h (F_k - alpha h (H v)_k) of each corner k, the factored Jacobian, the blocks
/// alpha^2 h^2 H_kl + alpha h C_kl for k <= l (kPair, column-major) and its elastic energy.
struct ElementTerms {
  double rhs[3][3];       ///< [corner][component]
  double factor[kFactors];
  double block[6][9];     ///< [pair][3 * column + row]
  double energy;          ///< A (Psi_uu + Psi_vv + Psi_uv), J
};

/// What a pass reads: the material, the state, the step and which terms are on.
struct PassInput {
  const Material* material;
  const Vec3* x;       ///< positions of every vertex
  const Vec3* v;       ///< velocities of every vertex
  StepFactors step;
  bool viscous;        ///< the strain-rate terms (eq. 6)
  bool spd;            ///< the Jacobian's negative parts clamped (JacobianMode::Spd)
};

/// Where a pass adds its terms: a system laid out as SystemPattern lays it out.
struct PassTarget {
  double* matrix;                          ///< CSR values
  double* rhs;
  const int* free_index;                   ///< per vertex: its block row, -1 when pinned
  const std::array<int, 9>* block_offset;  ///< per element (SystemPattern)
  const int* row_stride;                   ///< per block row
};

/// The elements of each assembly part in groups of the level's lanes, and the factored Jacobians
/// a kept matrix holds for them.
class ElementPass {
 public:
  virtual ~ElementPass() = default;
  /// Part `part`'s terms into `out`, every block added (and the factors kept, if `kept` is
  /// enabled). Returns the part's elastic energy; `formed` counts the elements whose blocks
  /// were added.
  virtual double run(WholeMatrix, int part, const PassInput& in, const PassTarget& out, KeptMatrix& kept,
                     int& formed) = 0;
  /// The same into the matrix in hand: only the blocks of the elements whose factors moved
  /// beyond kept's tolerance are added, as the blocks of the factors' change, their rows marked
  /// in `kept` for `part`. The right-hand side is added whole either way.
  virtual double run(KeptChanges, int part, const PassInput& in, const PassTarget& out, KeptMatrix& kept,
                     int& formed) = 0;
};

/// One instruction level's entry points.
struct ElementKernels {
  SimdLevel level;
  int lanes;  ///< doubles a vector holds
  /// A pass over the parts' elements (`parts[p]`: the indices of part p's elements, in order).
  std::unique_ptr<ElementPass> (*make_pass)(const std::vector<ElementRest>& elements,
                                            const std::vector<std::vector<int>>& parts);
  /// The terms of `elements` at state (x, v), lanes at a time, into out[0, elements.size()).
  void (*element_terms)(const std::vector<ElementRest>& elements, const PassInput& in,
                        ElementTerms* out);
  /// A material law on lanes at n strains: Psi, sigma and d sigma / d eps.
  void (*evaluate_law)(const StrainStressCurve& c, const double* eps, int n, double* psi,
                       double* sigma, double* dsigma);
};

/// The entry points of `level`; throws std::invalid_argument naming the level when this binary
/// lacks it or the CPU lacks its instructions.
const ElementKernels& element_kernels(SimdLevel level);

}  // namespace hapticloth::cloth
