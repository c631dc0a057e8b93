// The element algebra of eq. 9 on lanes: eqs. 3-7 and each element's terms of the system for
// kLanes elements at once, in structure-of-arrays form, so that every operation of the element
// algebra is one vector instruction for all of them.
//
// Why lanes: the element algebra (four fibre lengths, three material laws, the factored
// Jacobian and its nine system blocks) is a long chain of dependent scalar operations; one
// element at a time it took most of a small cloth's step, and on lanes it takes well under
// that (docs/performance.md, 'Performance of the step').
//
// Included only by an instruction level's translation unit (element_pass_lanes.hpp), which
// defines HAPTICLOTH_SIMD_NS (its namespace) and HAPTICLOTH_SIMD_LANES (doubles per vector: the
// width of the registers its -march gives). Everything here is in that namespace and has
// internal linkage, so that no code compiled for one level is linked in place of another's.
#pragma once

#if !defined(HAPTICLOTH_SIMD_NS) || !defined(HAPTICLOTH_SIMD_LANES)
#error "element_lanes.hpp belongs to an instruction level's translation unit"
#endif

#include <algorithm>
#include <cmath>
#include <vector>

#if defined(__AVX__)
#include <immintrin.h>
#endif

#include "cloth/curve.hpp"
#include "cloth/element_pass.hpp"

namespace hapticloth::cloth::HAPTICLOTH_SIMD_NS {
namespace {

#define HC_INLINE inline __attribute__((always_inline))

constexpr int kLanes = HAPTICLOTH_SIMD_LANES;
/// kLanes doubles as one vector (GCC vector extension), and a lane mask of the same width.
using Lanes = double __attribute__((vector_size(8 * kLanes)));
using Mask = long long __attribute__((vector_size(8 * kLanes)));

constexpr double kInvSqrt2 = 0.70710678118654752440;

HC_INLINE Lanes splat(double s) { return Lanes{} + s; }
HC_INLINE Lanes select(Mask m, Lanes a, Lanes b) { return m ? a : b; }
HC_INLINE Lanes max0(Lanes a) { return select(a > Lanes{}, a, Lanes{}); }
HC_INLINE Lanes vmin(Lanes a, Lanes b) { return select(a < b, a, b); }
HC_INLINE Lanes vabs(Lanes a) { return select(a < Lanes{}, -a, a); }
// The larger of a and b, and NaN if either is.
HC_INLINE Lanes vmax_nan(Lanes a, Lanes b) { return select((a > b) | (a != a), a, b); }
// One vsqrtpd with -fno-math-errno (the intrinsic trips GCC 12's -Wuninitialized).
HC_INLINE Lanes vsqrt(Lanes a) {
  Lanes r;
  for (int i = 0; i < kLanes; ++i) r[i] = std::sqrt(a[i]);
  return r;
}
// 1 / q, and 0 for a collapsed fibre (q = 0).
HC_INLINE Lanes inverse_or_zero(Lanes q) { return select(q > Lanes{}, 1.0 / q, Lanes{}); }

struct Vec3L {
  Lanes c[3];
};
HC_INLINE Lanes dot(const Vec3L& a, const Vec3L& b) {
  return a.c[0] * b.c[0] + a.c[1] * b.c[1] + a.c[2] * b.c[2];
}

/// kLanes elements' rest data in lanes, and which elements they are. A list whose length is
/// not a multiple of kLanes ends in a group whose last lanes repeat its last element (so that
/// they compute something finite); only the first `count` are real.
struct ElementGroup {
  int t[kLanes];         ///< element index
  int v[3][kLanes];      ///< its corners
  int count = 0;
  Lanes ru[3], rv[3], area;
};

/// The groups of the elements `order` lists, in that order.
std::vector<ElementGroup> group_elements(const std::vector<ElementRest>& elements,
                                         const std::vector<int>& order) {
  std::vector<ElementGroup> groups;
  for (std::size_t first = 0; first < order.size(); first += kLanes) {
    ElementGroup g;
    g.count = static_cast<int>(std::min<std::size_t>(kLanes, order.size() - first));
    for (int l = 0; l < kLanes; ++l) {
      const int t = order[first + std::min(l, g.count - 1)];
      const ElementRest& e = elements[t];
      g.t[l] = t;
      for (int k = 0; k < 3; ++k) {
        g.v[k][l] = e.v[k];
        g.ru[k][l] = e.ru[k];
        g.rv[k][l] = e.rv[k];
      }
      g.area[l] = e.area;
    }
    groups.push_back(g);
  }
  return groups;
}

/// One group's terms of eq. 9, lane by lane (ElementTerms, cloth/element_pass.hpp, per lane).
struct GroupTerms {
  Lanes rhs[3][3];          ///< [corner][component]
  Lanes factor[kFactors];   ///< see kFactors
  Lanes block[6][9];        ///< [pair][3 * column + row]
  Lanes energy;             ///< A (Psi_uu + Psi_vv + Psi_uv), J
};

/// A group's blocks lane by lane, each row-major (9 doubles, row r at [3r, 3r + 3)): the rows
/// that the scatter adds to a block row's values, three contiguous doubles each. `rows[p][l]`
/// is lane l's block of pair p as GroupTerms holds it (block (k, l) for k <= l); for the pairs
/// with k < l, `rows_t[p][l]` is its transpose (block (l, k)). The same numbers as GroupTerms,
/// moved only, so the scatter's sums do not change.
struct LaneBlocks {
  alignas(64) double rows[6][kLanes][9];
  alignas(64) double rows_t[6][kLanes][9];
};

/// A material law on lanes: Psi, sigma and d sigma / d eps of StrainStressCurve::evaluate_all.
HC_INLINE void evaluate_lanes(const StrainStressCurve& c, Lanes eps, Lanes& psi, Lanes& s,
                              Lanes& ds) {
  // |eps| for an odd (shear) law, the positive part for a tensile one (its negative side is
  // linear, below)
  const Mask neg = eps < Lanes{};
  Lanes e = c.odd ? select(neg, -eps, eps) : max0(eps);
  // Beyond the validated range the law continues linearly with its tangent there (C1):
  // the spline at min(e, max_strain), extended by d = e - max_strain >= 0.
  const Lanes ec = vmin(e, splat(c.max_strain));
  const Lanes d = e - ec;
  Lanes p0, s0, k0;
  detail::spline_all<Lanes>(c, ec, p0, s0, k0);
  s = s0 + k0 * d;
  ds = k0;
  psi = p0 + d * (s0 + 0.5 * k0 * d);
  if (c.odd) {
    s = select(neg, -s, s);  // the tangent and the energy are even
    return;
  }
  // tensile law below zero strain: linear, the "A eps" term, scaled
  const double k = c.compression_scale * c.B[0][1];
  s = select(neg, c.B[0][0] + k * eps, s);
  ds = select(neg, splat(k), ds);
  psi = select(neg, eps * (c.B[0][0] + 0.5 * k * eps), psi);
}

// Eq. 3: U, V and the diagonals S = U + V, D = U - V of eq. 4, their lengths and directions,
// and eq. 5: the rates U', V'.
struct Fibres {
  Vec3L Uv, Vv;                 // U', V'
  Lanes qu, qv, qs, qd;         // |U|, |V|, |S|, |D|
  Lanes iu, iv, is, id;         // their inverses (0 for a collapsed fibre)
  Vec3L nu, nv, ns, nd;         // unit vectors
  Vec3L va, vb;                 // d eps_uv / dU, d eps_uv / dV
};

HC_INLINE void fibres(const ElementGroup& g, const Vec3* X, const Vec3* Vel, Fibres& f) {
  Vec3L x[3], v[3];
  for (int k = 0; k < 3; ++k)
    for (int l = 0; l < kLanes; ++l) {
      const double* xp = X[g.v[k][l]].data();
      const double* vp = Vel[g.v[k][l]].data();
      for (int i = 0; i < 3; ++i) {
        x[k].c[i][l] = xp[i];
        v[k].c[i][l] = vp[i];
      }
    }
  Vec3L U, V, S, D;
  for (int i = 0; i < 3; ++i) {
    U.c[i] = g.ru[0] * x[0].c[i] + g.ru[1] * x[1].c[i] + g.ru[2] * x[2].c[i];
    V.c[i] = g.rv[0] * x[0].c[i] + g.rv[1] * x[1].c[i] + g.rv[2] * x[2].c[i];
    S.c[i] = U.c[i] + V.c[i];
    D.c[i] = U.c[i] - V.c[i];
    f.Uv.c[i] = g.ru[0] * v[0].c[i] + g.ru[1] * v[1].c[i] + g.ru[2] * v[2].c[i];
    f.Vv.c[i] = g.rv[0] * v[0].c[i] + g.rv[1] * v[1].c[i] + g.rv[2] * v[2].c[i];
  }
  f.qu = vsqrt(dot(U, U)), f.qv = vsqrt(dot(V, V));
  f.qs = vsqrt(dot(S, S)), f.qd = vsqrt(dot(D, D));
  f.iu = inverse_or_zero(f.qu), f.iv = inverse_or_zero(f.qv);
  f.is = inverse_or_zero(f.qs), f.id = inverse_or_zero(f.qd);
  for (int i = 0; i < 3; ++i) {
    f.nu.c[i] = U.c[i] * f.iu;
    f.nv.c[i] = V.c[i] * f.iv;
    f.ns.c[i] = S.c[i] * f.is;
    f.nd.c[i] = D.c[i] * f.id;
    f.va.c[i] = (f.ns.c[i] - f.nd.c[i]) * kInvSqrt2;
    f.vb.c[i] = (f.ns.c[i] + f.nd.c[i]) * kInvSqrt2;
  }
}

// Stress of each strain: the total (elastic + viscous), and the elastic law's tangent.
struct Stress {
  Lanes t_uu, t_vv, t_uv;
  Lanes k_uu, k_vv, k_uv;
};

// Eq. 4 strains through the material laws, plus eq. 6 strain rates times the viscosities.
// Returns the elements' elastic energies.
template <bool kViscous>
HC_INLINE Lanes stress(const Material& mat, Lanes A, const Fibres& f, Stress& st) {
  const Lanes e_uu = f.qu - 1.0, e_vv = f.qv - 1.0, e_uv = (f.qs - f.qd) * kInvSqrt2;
  Lanes p_uu, s_uu, p_vv, s_vv, p_uv, s_uv;
  evaluate_lanes(mat.weft, e_uu, p_uu, s_uu, st.k_uu);
  evaluate_lanes(mat.warp, e_vv, p_vv, s_vv, st.k_vv);
  evaluate_lanes(mat.shear, e_uv, p_uv, s_uv, st.k_uv);
  st.t_uu = s_uu, st.t_vv = s_vv, st.t_uv = s_uv;
  if constexpr (kViscous) {
    Vec3L sum, dif;
    for (int i = 0; i < 3; ++i) {
      sum.c[i] = f.Uv.c[i] + f.Vv.c[i];
      dif.c[i] = f.Uv.c[i] - f.Vv.c[i];
    }
    st.t_uu += mat.weft.viscosity * dot(f.nu, f.Uv);
    st.t_vv += mat.warp.viscosity * dot(f.nv, f.Vv);
    st.t_uv += mat.shear.viscosity * (dot(f.ns, sum) - dot(f.nd, dif)) * kInvSqrt2;
  }
  return A * (p_uu + p_vv + p_uv);
}

// A symmetric 3x3 on lanes, full (column-major), and its rank-one update S += c n n^T.
struct Mat3L {
  Lanes m[9];
};
HC_INLINE void add_rank1(Mat3L& S, Lanes c, const Vec3L& n) {
  for (int col = 0; col < 3; ++col)
    for (int r = 0; r < 3; ++r) S.m[3 * col + r] += c * n.c[r] * n.c[col];
}
HC_INLINE void add_outer(Mat3L& S, Lanes c, const Vec3L& a, const Vec3L& b) {  // S += c a b^T
  for (int col = 0; col < 3; ++col)
    for (int r = 0; r < 3; ++r) S.m[3 * col + r] += c * a.c[r] * b.c[col];
}
HC_INLINE void add_identity(Mat3L& S, Lanes c) {
  for (int i = 0; i < 3; ++i) S.m[4 * i] += c;
}

// The factored Jacobian (see ElementEval) with the tangents and (for the geometric part) the
// stresses clamped at zero in Spd mode, c_f = A g_f / q_f per fibre:
//   P = (cu + cs + cd) I + (A ku - cu) nu nu^T - cs ns ns^T - cd nd nd^T + A ks a a^T
//   Q = (cv + cs + cd) I + (A kv - cv) nv nv^T - cs ns ns^T - cd nd nd^T + A ks b b^T
//   W = (cs - cd) I - cs ns ns^T + cd nd nd^T + A ks a b^T
template <bool kSpd>
HC_INLINE void jacobian_factors(Lanes A, const Fibres& f, const Stress& st, Mat3L& P, Mat3L& Q,
                                Mat3L& W) {
  auto clamp = [](Lanes c) { return kSpd ? max0(c) : c; };
  const Lanes ku = clamp(st.k_uu), kv = clamp(st.k_vv), Aks = A * clamp(st.k_uv);
  const Lanes cu = A * clamp(st.t_uu) * f.iu, cv = A * clamp(st.t_vv) * f.iv;
  const Lanes cs = A * clamp(st.t_uv * kInvSqrt2) * f.is;
  const Lanes cd = A * clamp(-st.t_uv * kInvSqrt2) * f.id;
  Mat3L SD{};
  add_rank1(SD, -cs, f.ns);
  add_rank1(SD, -cd, f.nd);
  P = SD, Q = SD;
  add_identity(P, cu + cs + cd);
  add_identity(Q, cv + cs + cd);
  add_rank1(P, A * ku - cu, f.nu);
  add_rank1(P, Aks, f.va);
  add_rank1(Q, A * kv - cv, f.nv);
  add_rank1(Q, Aks, f.vb);
  W = Mat3L{};
  add_identity(W, cs - cd);
  add_rank1(W, -cs, f.ns);
  add_rank1(W, cd, f.nd);
  add_outer(W, Aks, f.va, f.vb);
}

/// The right-hand sides, factored Jacobians and energies of every element of `g` at positions
/// X and velocities V (whole-mesh arrays); not the blocks (system_blocks). kViscous: the
/// strain-rate terms (eq. 6); kSpd: the Jacobian's negative parts clamped (JacobianMode::Spd).
/// Same algebra as evaluate_element, which the finite-difference tests check
/// (test_element_pass holds the two together at every level).
template <bool kViscous, bool kSpd>
void element_terms(const ElementGroup& g, const Material& mat, const Vec3* X, const Vec3* V,
                   StepFactors sf, GroupTerms& out) {
  const double h = sf.h, ah = sf.alpha * h, aahh = ah * ah;
  const Lanes A = g.area;
  Fibres f;
  fibres(g, X, V, f);
  Stress st;
  out.energy = stress<kViscous>(mat, A, f, st);
  // Forces F_k = ru_k Fu + rv_k Fv (the exact gradient; eq. 7 for small shear).
  Vec3L Fu, Fv;
  for (int i = 0; i < 3; ++i) {
    Fu.c[i] = -A * (st.t_uu * f.nu.c[i] + st.t_uv * f.va.c[i]);
    Fv.c[i] = -A * (st.t_vv * f.nv.c[i] + st.t_uv * f.vb.c[i]);
  }
  Mat3L P, Q, W;
  jacobian_factors<kSpd>(A, f, st, P, Q, W);
  // Right-hand side of eq. 9 per corner, h (F_k - alpha h H v) = ru_k gu + rv_k gv, with
  // H v = ru_k hu + rv_k hv, hu = P U' + W V', hv = Q V' + W^T U'. Pinned neighbours' velocity
  // enters here, which is how their prescribed motion reaches the solve.
  Vec3L gu, gv;
  for (int r = 0; r < 3; ++r) {
    Lanes su{}, sv{};
    for (int c = 0; c < 3; ++c) {
      su += P.m[3 * c + r] * f.Uv.c[c] + W.m[3 * c + r] * f.Vv.c[c];
      sv += Q.m[3 * c + r] * f.Vv.c[c] + W.m[3 * r + c] * f.Uv.c[c];
    }
    gu.c[r] = h * (Fu.c[r] - ah * su);
    gv.c[r] = h * (Fv.c[r] - ah * sv);
  }
  for (int k = 0; k < 3; ++k)
    for (int r = 0; r < 3; ++r) out.rhs[k][r] = g.ru[k] * gu.c[r] + g.rv[k] * gv.c[r];
  // System blocks alpha^2 h^2 H + alpha h C in the same factored form. C = A sum eta grad(eps)
  // grad(eps)^T: Pc = eta_u nu nu^T + eta_s a a^T, Qc = eta_v nv nv^T + eta_s b b^T,
  // Wc = eta_s a b^T.
  for (int i = 0; i < 9; ++i) {
    P.m[i] *= aahh;
    Q.m[i] *= aahh;
    W.m[i] *= aahh;
  }
  if constexpr (kViscous) {
    const Lanes c1 = ah * mat.weft.viscosity * A, c2 = ah * mat.warp.viscosity * A;
    const Lanes c3 = ah * mat.shear.viscosity * A;
    add_rank1(P, c1, f.nu);
    add_rank1(P, c3, f.va);
    add_rank1(Q, c2, f.nv);
    add_rank1(Q, c3, f.vb);
    add_outer(W, c3, f.va, f.vb);
  }
  for (int r = 0, i = 0; r < 3; ++r)
    for (int c = r; c < 3; ++c, ++i) {
      out.factor[kFactorP + i] = P.m[3 * c + r];
      out.factor[kFactorQ + i] = Q.m[3 * c + r];
    }
  for (int i = 0; i < 9; ++i) out.factor[kFactorW + i] = W.m[i];
}

/// element_terms for the step's modes (PassInput::viscous, spd).
HC_INLINE void element_terms(const ElementGroup& g, const PassInput& in, GroupTerms& out) {
  const Material& m = *in.material;
  if (in.viscous)
    in.spd ? element_terms<true, true>(g, m, in.x, in.v, in.step, out)
           : element_terms<true, false>(g, m, in.x, in.v, in.step, out);
  else
    in.spd ? element_terms<false, true>(g, m, in.x, in.v, in.step, out)
           : element_terms<false, false>(g, m, in.x, in.v, in.step, out);
}

/// The system blocks of factored Jacobians `factor` (kFactors lanes, as GroupTerms holds them)
/// for the corners of `g`: block (k, l) = ru_k ru_l P + rv_k rv_l Q + ru_k rv_l W +
/// rv_k ru_l W^T, into `block` as GroupTerms holds it.
HC_INLINE void system_blocks(const ElementGroup& g, const Lanes* factor, Lanes (&block)[6][9]) {
  // The symmetric factors' entry (r, c) from their upper entries.
  static constexpr int kUpper[9] = {0, 1, 2, 1, 3, 4, 2, 4, 5};
  const Lanes* P = factor + kFactorP;
  const Lanes* Q = factor + kFactorQ;
  const Lanes* W = factor + kFactorW;
  for (int k = 0; k < 3; ++k)
    for (int l = k; l < 3; ++l) {
      const Lanes c1 = g.ru[k] * g.ru[l], c2 = g.rv[k] * g.rv[l];
      const Lanes c3 = g.ru[k] * g.rv[l], c4 = g.rv[k] * g.ru[l];
      Lanes* blk = block[kPair[k][l]];
      for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 3; ++r)
          blk[3 * c + r] = c1 * P[kUpper[3 * c + r]] + c2 * Q[kUpper[3 * c + r]] +
                           c3 * W[3 * c + r] + c4 * W[3 * r + c];
    }
}

// dst[l][j] = src[order[j]][l]: the entries that `order` lists, lane by lane. The first eight
// entries are transposed in registers where the level has a shuffle for its width (an 8x8 with
// AVX-512, two 4x4 with AVX); the ninth is copied.
#if HAPTICLOTH_SIMD_LANES == 8 && defined(__AVX512F__)
// GCC 12 takes the intrinsics' _mm512_undefined_pd() for an uninitialised read.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
HC_INLINE void to_lanes(const Lanes* src, const int (&order)[9], double (&dst)[kLanes][9]) {
#if HAPTICLOTH_SIMD_LANES == 8 && defined(__AVX512F__)
  __m512d t[8], u[8];
  for (int i = 0; i < 4; ++i) {
    const __m512d a = reinterpret_cast<__m512d>(src[order[2 * i]]);
    const __m512d b = reinterpret_cast<__m512d>(src[order[2 * i + 1]]);
    t[2 * i] = _mm512_unpacklo_pd(a, b);
    t[2 * i + 1] = _mm512_unpackhi_pd(a, b);
  }
  for (int h = 0; h < 2; ++h)  // (t0, t2) and (t1, t3) into u0-u3; (t4, t6), (t5, t7) into u4-u7
    for (int i = 0; i < 2; ++i) {
      u[4 * h + i] = _mm512_shuffle_f64x2(t[4 * h + i], t[4 * h + i + 2], 0x88);
      u[4 * h + i + 2] = _mm512_shuffle_f64x2(t[4 * h + i], t[4 * h + i + 2], 0xdd);
    }
  for (int i = 0; i < 4; ++i) {
    _mm512_storeu_pd(dst[i], _mm512_shuffle_f64x2(u[i], u[i + 4], 0x88));
    _mm512_storeu_pd(dst[i + 4], _mm512_shuffle_f64x2(u[i], u[i + 4], 0xdd));
  }
#elif HAPTICLOTH_SIMD_LANES == 4 && defined(__AVX__)
  for (int half = 0; half < 2; ++half) {  // entries 0-3, then 4-7
    const int* o = order + 4 * half;
    const __m256d r0 = reinterpret_cast<__m256d>(src[o[0]]), r1 = reinterpret_cast<__m256d>(src[o[1]]);
    const __m256d r2 = reinterpret_cast<__m256d>(src[o[2]]), r3 = reinterpret_cast<__m256d>(src[o[3]]);
    const __m256d t0 = _mm256_unpacklo_pd(r0, r1), t1 = _mm256_unpackhi_pd(r0, r1);
    const __m256d t2 = _mm256_unpacklo_pd(r2, r3), t3 = _mm256_unpackhi_pd(r2, r3);
    _mm256_storeu_pd(dst[0] + 4 * half, _mm256_permute2f128_pd(t0, t2, 0x20));
    _mm256_storeu_pd(dst[1] + 4 * half, _mm256_permute2f128_pd(t1, t3, 0x20));
    _mm256_storeu_pd(dst[2] + 4 * half, _mm256_permute2f128_pd(t0, t2, 0x31));
    _mm256_storeu_pd(dst[3] + 4 * half, _mm256_permute2f128_pd(t1, t3, 0x31));
  }
#else
  for (int l = 0; l < kLanes; ++l)
    for (int j = 0; j < 8; ++j) dst[l][j] = src[order[j]][l];
#endif
  for (int l = 0; l < kLanes; ++l) dst[l][8] = src[order[8]][l];
}
#if HAPTICLOTH_SIMD_LANES == 8 && defined(__AVX512F__)
#pragma GCC diagnostic pop
#endif

/// GroupTerms' blocks into LaneBlocks.
HC_INLINE void lane_blocks(const GroupTerms& terms, LaneBlocks& out) {
  // GroupTerms holds a block column-major (entry 3 c + r): row-major is its transpose's order.
  static constexpr int kRowMajor[9] = {0, 3, 6, 1, 4, 7, 2, 5, 8};
  static constexpr int kColumnMajor[9] = {0, 1, 2, 3, 4, 5, 6, 7, 8};
  for (int k = 0; k < 3; ++k)
    for (int l = k; l < 3; ++l) {
      const int p = kPair[k][l];
      to_lanes(terms.block[p], kRowMajor, out.rows[p]);
      if (l != k) to_lanes(terms.block[p], kColumnMajor, out.rows_t[p]);
    }
}

}  // namespace
}  // namespace hapticloth::cloth::HAPTICLOTH_SIMD_NS
