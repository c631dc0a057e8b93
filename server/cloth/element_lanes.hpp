// The element pass of eq. 9 on lanes: eqs. 3-7 and each element's terms of the system for
// kLanes elements at once, in structure-of-arrays form, so that every operation of the element
// algebra is one vector instruction for all of them. The integrator scatters the terms into its
// matrix rows (Integrator::assemble_cloth).
//
// Why lanes: the element algebra (four fibre lengths, three material laws, the factored
// Jacobian and its nine system blocks) is a long chain of dependent scalar operations. One
// element at a time the pass took 0.130 ms of the 968-triangle cloth's 0.189 ms step; on
// lanes it takes 0.080 ms, half of it the scatter (docs/performance.md, BENCHMARKS.md "Force
// fidelity", 2026-11-26 night).
#pragma once

#include <vector>

#include "cloth/element.hpp"
#include "cloth/material.hpp"

namespace hapticloth::cloth {

inline constexpr int kLanes = 8;
/// kLanes doubles as one vector (GCC vector extension: lowered to AVX-512, or to narrower
/// registers where the CPU has none).
using Lanes = double __attribute__((vector_size(8 * kLanes)));

/// kLanes elements' rest data in lanes, and which elements they are. A list whose length is
/// not a multiple of kLanes ends in a group whose last lanes repeat its last element; only the
/// first `count` are real.
struct ElementGroup {
  int t[kLanes];         ///< element index
  int v[3][kLanes];      ///< its corners
  int count = 0;
  Lanes ru[3], rv[3], area;
};

/// The groups of the elements `order` lists, in that order.
std::vector<ElementGroup> group_elements(const std::vector<ElementRest>& elements,
                                         const std::vector<int>& order);

/// The factored system Jacobian of an element, alpha^2 h^2 (P, Q, W) + alpha h (Pc, Qc, Wc)
/// (element_terms): the symmetric P and Q by their upper entries (00, 01, 02, 11, 12, 22), then
/// W whole, column-major. Every system block is linear in these (system_blocks), which is what
/// lets a kept matrix take an element's change as the blocks of its factors' difference.
inline constexpr int kFactors = 21;
inline constexpr int kFactorP = 0, kFactorQ = 6, kFactorW = 12;

/// One group's terms of eq. 9, lane by lane: the right-hand side h (F_k - alpha h (H v)_k) of
/// each corner k, the factored Jacobian, and (system_blocks) the blocks alpha^2 h^2 H_kl +
/// alpha h C_kl for k <= l (pair index kPair[k][l]; (l, k) is the transpose), column-major.
struct ElementTerms {
  Lanes rhs[3][3];          ///< [corner][component]
  Lanes factor[kFactors];   ///< see kFactors
  Lanes block[6][9];        ///< [pair][3 * column + row]
  Lanes energy;             ///< A (Psi_uu + Psi_vv + Psi_uv), J
};
inline constexpr int kPair[3][3] = {{0, 1, 2}, {1, 3, 4}, {2, 4, 5}};

/// A group's blocks lane by lane, each row-major (9 doubles, row r at [3r, 3r + 3)): the rows
/// that the scatter adds to a block row's values, three contiguous doubles each. `rows[p][l]`
/// is lane l's block of pair p as ElementTerms holds it (block (k, l) for k <= l); for the
/// pairs with k < l, `rows_t[p][l]` is its transpose (block (l, k)). The same numbers as
/// ElementTerms, moved only, so the scatter's sums do not change.
struct LaneBlocks {
  alignas(64) double rows[6][kLanes][9];
  alignas(64) double rows_t[6][kLanes][9];
};

/// ElementTerms' blocks into LaneBlocks: with AVX-512 an 8x8 transpose of each block's first
/// eight entries in registers (its ninth, the (2, 2) entry, is copied), else entry by entry.
void lane_blocks(const ElementTerms& terms, LaneBlocks& out);

struct StepFactors {
  double h;       ///< the (sub)step, s
  double alpha;   ///< implicitness (eq. 8)
};

/// The right-hand sides, factored Jacobians and energies of every element of `g` at positions
/// X and velocities V (whole-mesh arrays); not the blocks (system_blocks).
/// kViscous: the strain-rate terms (eq. 6); kSpd: the Jacobian's negative parts clamped
/// (JacobianMode::Spd). Same algebra as evaluate_element, which the finite-difference tests
/// check (test_integrator's FusedAssembly holds the two together).
template <bool kViscous, bool kSpd>
void element_terms(const ElementGroup& g, const Material& mat, const Vec3* X, const Vec3* V,
                   StepFactors f, ElementTerms& out);

/// The system blocks of factored Jacobians `factor` (kFactors lanes, as ElementTerms holds
/// them) for the corners of `g`: block (k, l) = ru_k ru_l P + rv_k rv_l Q + ru_k rv_l W +
/// rv_k ru_l W^T, into `block` as ElementTerms holds it.
void system_blocks(const ElementGroup& g, const Lanes* factor, Lanes (&block)[6][9]);

/// A material law on lanes: Psi, sigma and d sigma / d eps of StrainStressCurve::evaluate_all.
void evaluate_lanes(const StrainStressCurve& c, Lanes eps, Lanes& psi, Lanes& sigma,
                    Lanes& dsigma);

}  // namespace hapticloth::cloth
