// An instruction level's element pass (ElementPass, cloth/element_pass.hpp) on the lanes of
// element_lanes.hpp: the groups of each assembly part, the kept factored Jacobians, and the
// scatter of each lane's terms into the system rows of its free corners. The level's translation
// unit (element_pass_baseline.cpp, _avx2.cpp, _avx512.cpp) defines HAPTICLOTH_SIMD_NS and
// HAPTICLOTH_SIMD_LANES, includes this header and exports level_kernels() from its namespace.
#pragma once

#include <cstring>
#include <limits>
#include <memory>
#include <vector>

#include "cloth/element_lanes.hpp"
#include "cloth/kept_matrix.hpp"

namespace hapticloth::cloth::HAPTICLOTH_SIMD_NS {
namespace {

// Adds a row-major 3x3 block B to the values at `dst` whose rows are `stride` apart: three
// contiguous doubles a row, one masked vector each with AVX-512 (the fourth value may be another
// thread's row, so it is neither read nor written).
HC_INLINE void add_block_rows(double* dst, int stride, const double* B) {
  for (int r = 0; r < 3; ++r, dst += stride) {
#if defined(__AVX512F__) && defined(__AVX512VL__)
    const __m256d a = _mm256_maskz_loadu_pd(0x7, dst), b = _mm256_maskz_loadu_pd(0x7, B + 3 * r);
    _mm256_mask_storeu_pd(dst, 0x7, _mm256_add_pd(a, b));
#else
    for (int c = 0; c < 3; ++c) dst[c] += B[3 * r + c];
#endif
  }
}

// The factored Jacobians a kept matrix was last formed with, one group's lanes.
struct KeptFactors {
  Lanes f[kFactors];
};

// Keeps the group's factors (a matrix formed whole).
HC_INLINE void keep_factors(const GroupTerms& terms, KeptFactors& k) {
  for (int i = 0; i < kFactors; ++i) k.f[i] = terms.factor[i];
}

// A kept step: the lanes whose factors moved by more than `tolerance` of their largest entry
// (or are not finite) take the new ones, and `terms.factor` becomes their difference (zero in
// the other lanes). Returns those lanes as bits (lane l: bit l), of the group's first `count`.
HC_INLINE unsigned take_changes(double tolerance, int count, GroupTerms& terms, KeptFactors& k) {
  Lanes dmax{}, fmax{};
  for (int i = 0; i < kFactors; ++i) {
    dmax = vmax_nan(dmax, vabs(terms.factor[i] - k.f[i]));
    fmax = vmax_nan(fmax, vabs(terms.factor[i]));
  }
  // Held where the change is within the tolerance and the factors are finite: a NaN or an
  // infinity moves, and so reaches the solve, which fails the step.
  const Mask held = (dmax <= tolerance * fmax) & (fmax <= std::numeric_limits<double>::max());
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

class LanePass final : public ElementPass {
 public:
  LanePass(const std::vector<ElementRest>& elements, const std::vector<std::vector<int>>& parts) {
    for (const auto& order : parts) {
      groups_.push_back(group_elements(elements, order));
      kept_.emplace_back(groups_.back().size());
    }
  }

  double run(WholeMatrix form, int part, const PassInput& in, const PassTarget& out, KeptMatrix& kept,
             int& formed) override {
    return run_as(form, part, in, out, kept, formed);
  }
  double run(KeptChanges form, int part, const PassInput& in, const PassTarget& out, KeptMatrix& kept,
             int& formed) override {
    return run_as(form, part, in, out, kept, formed);
  }

 private:
  template <class Form>
  double run_as(Form form, int part, const PassInput& in, const PassTarget& out, KeptMatrix& kept, int& formed) {
    GroupTerms terms;  // 5 kB and 7 kB with AVX-512, on the stack of the thread that runs the part
    LaneBlocks blocks;
    const std::vector<ElementGroup>& groups = groups_[part];
    std::vector<KeptFactors>& factors = kept_[part];
    double energy = 0.0;
    formed = 0;
    for (std::size_t i = 0; i < groups.size(); ++i) {
      const ElementGroup& g = groups[i];
      element_terms(g, in, terms);
      const unsigned lanes = lanes_to_form(form, kept, g, terms, factors[i]);
      if (lanes) {
        system_blocks(g, terms.factor, terms.block);
        lane_blocks(terms, blocks);
      }
      energy += scatter(g, terms, blocks, lanes, out, rows_to_mark(form, kept), part);
      formed += __builtin_popcount(lanes);
    }
    return energy;
  }

  // The lanes whose blocks go in (bit l: lane l): all of a matrix formed whole (their factors
  // kept for the next steps' changes when a kept matrix is on); of a kept one, those whose
  // factors moved, their terms turned into the change.
  static unsigned lanes_to_form(WholeMatrix, const KeptMatrix& kept, const ElementGroup& g, GroupTerms& terms,
                                KeptFactors& factors) {
    if (kept.enabled()) keep_factors(terms, factors);
    return (1u << g.count) - 1;
  }
  static unsigned lanes_to_form(KeptChanges, const KeptMatrix& kept, const ElementGroup& g, GroupTerms& terms,
                                KeptFactors& factors) {
    return take_changes(kept.tolerance(), g.count, terms, factors);
  }
  static KeptMatrix* rows_to_mark(WholeMatrix, KeptMatrix&) { return nullptr; }
  static KeptMatrix* rows_to_mark(KeptChanges, KeptMatrix& kept) { return &kept; }

  // A group's terms at its elements' free vertices (pinned ones have no row): the right-hand
  // sides, the blocks (k, l) for k <= l, and (l, k) as their transposes, row by row (the same sums
  // in the same order as entry by entry); the blocks of the lanes in `lanes` only (bit l: lane l),
  // whose rows a kept matrix marks changed for `part`. Returns the group's elastic energy.
  static double scatter(const ElementGroup& g, const GroupTerms& terms, const LaneBlocks& blocks,
                        unsigned lanes, const PassTarget& out, KeptMatrix* kept, int part) {
    double energy = 0.0;
    for (int lane = 0; lane < g.count; ++lane) {
      energy += terms.energy[lane];
      int fk[3];
      for (int k = 0; k < 3; ++k) {
        fk[k] = out.free_index[g.v[k][lane]];
        if (fk[k] < 0) continue;
        for (int r = 0; r < 3; ++r) out.rhs[3 * fk[k] + r] += terms.rhs[k][r][lane];
      }
      if (!(lanes >> lane & 1u)) continue;
      const auto& off = out.block_offset[g.t[lane]];
      for (int k = 0; k < 3; ++k) {
        if (fk[k] < 0) continue;
        if (kept) kept->mark(part, fk[k]);
        for (int l = k; l < 3; ++l) {
          if (fk[l] < 0) continue;
          const int p = kPair[k][l];
          add_block_rows(out.matrix + off[k * 3 + l], out.row_stride[fk[k]], blocks.rows[p][lane]);
          if (l != k)
            add_block_rows(out.matrix + off[l * 3 + k], out.row_stride[fk[l]], blocks.rows_t[p][lane]);
        }
      }
    }
    return energy;
  }

  std::vector<std::vector<ElementGroup>> groups_;  // per part
  std::vector<std::vector<KeptFactors>> kept_;     // per part, per group
};

std::unique_ptr<ElementPass> make_pass(const std::vector<ElementRest>& elements,
                                       const std::vector<std::vector<int>>& parts) {
  return std::make_unique<LanePass>(elements, parts);
}

void terms_of(const std::vector<ElementRest>& elements, const PassInput& in, ElementTerms* out) {
  std::vector<int> order(elements.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  GroupTerms t;
  for (const ElementGroup& g : group_elements(elements, order)) {
    element_terms(g, in, t);
    system_blocks(g, t.factor, t.block);
    for (int l = 0; l < g.count; ++l) {
      ElementTerms& e = out[g.t[l]];
      for (int k = 0; k < 3; ++k)
        for (int r = 0; r < 3; ++r) e.rhs[k][r] = t.rhs[k][r][l];
      for (int i = 0; i < kFactors; ++i) e.factor[i] = t.factor[i][l];
      for (int p = 0; p < 6; ++p)
        for (int j = 0; j < 9; ++j) e.block[p][j] = t.block[p][j][l];
      e.energy = t.energy[l];
    }
  }
}

void law_of(const StrainStressCurve& c, const double* eps, int n, double* psi, double* s,
            double* ds) {
  for (int first = 0; first < n; first += kLanes) {
    const int count = std::min(kLanes, n - first);
    Lanes e{}, p, sl, dl;
    for (int l = 0; l < count; ++l) e[l] = eps[first + l];
    evaluate_lanes(c, e, p, sl, dl);
    for (int l = 0; l < count; ++l) {
      psi[first + l] = p[l];
      s[first + l] = sl[l];
      ds[first + l] = dl[l];
    }
  }
}

}  // namespace

const ElementKernels& level_kernels() {
  static const ElementKernels k{HAPTICLOTH_SIMD_LEVEL, kLanes, make_pass, terms_of, law_of};
  return k;
}

}  // namespace hapticloth::cloth::HAPTICLOTH_SIMD_NS
