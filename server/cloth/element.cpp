#include "cloth/element.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace hapticloth::cloth {

namespace {
constexpr double kInvSqrt2 = 0.70710678118654752440;
}

ElementRest make_element(int a, int b, int c, const double uv[3][2]) {
  const double ua = uv[0][0], va = uv[0][1];
  const double ub = uv[1][0], vb = uv[1][1];
  const double uc = uv[2][0], vc = uv[2][1];
  // Eq. 2
  const double d = ua * (vb - vc) + ub * (vc - va) + uc * (va - vb);
  const double scale = std::max({std::abs(ua - ub), std::abs(ua - uc), std::abs(va - vb),
                                 std::abs(va - vc), 1e-300});
  if (!std::isfinite(d) || std::abs(d) <= 1e-12 * scale * scale) {
    std::ostringstream os;
    os << "degenerate triangle (" << a << ", " << b << ", " << c << ") in weave coordinates";
    throw std::invalid_argument(os.str());
  }
  ElementRest e;
  e.v[0] = a;
  e.v[1] = b;
  e.v[2] = c;
  e.ru[0] = (vb - vc) / d;
  e.ru[1] = -(va - vc) / d;
  e.ru[2] = (va - vb) / d;
  e.rv[0] = -(ub - uc) / d;
  e.rv[1] = (ua - uc) / d;
  e.rv[2] = -(ua - ub) / d;
  e.area = 0.5 * std::abs(d);
  return e;
}

Strains element_strains(const ElementRest& e, const Vec3& xa, const Vec3& xb, const Vec3& xc) {
  // Eq. 3, eq. 4 (shear from the diagonals U+V and U-V)
  const Vec3 U = e.ru[0] * xa + e.ru[1] * xb + e.ru[2] * xc;
  const Vec3 V = e.rv[0] * xa + e.rv[1] * xb + e.rv[2] * xc;
  Strains s;
  s.uu = U.norm() - 1.0;
  s.vv = V.norm() - 1.0;
  s.uv = ((U + V).norm() - (U - V).norm()) * kInvSqrt2;
  return s;
}

double element_energy(const ElementRest& e, const Material& m, const Vec3& xa, const Vec3& xb,
                      const Vec3& xc) {
  const Strains s = element_strains(e, xa, xb, xc);
  return e.area * (m.weft.energy(s.uu) + m.warp.energy(s.vv) + m.shear.energy(s.uv));
}

namespace {

#define HC_INLINE inline __attribute__((always_inline))

// out = c1 P + c2 Q + c3 W + c4 W^T, written out: Eigen's expression for four 3x3 terms with a
// transpose is not unrolled by the compiler and dominated the assembly.
HC_INLINE void combine(Mat3& out, double c1, const Mat3& P, double c2, const Mat3& Q, double c3,
                       const Mat3& W, double c4) {
  const double* p = P.data();
  const double* q = Q.data();
  const double* w = W.data();
  double* o = out.data();
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i)
      o[3 * j + i] = c1 * p[3 * j + i] + c2 * q[3 * j + i] + c3 * w[3 * j + i] + c4 * w[3 * i + j];
}

// One "fibre" of the element: W = sum_k r_k x_k, with q = |W| and n = W / q.
struct Fibre {
  double r[3];
  Vec3 W;
  double q;
  Vec3 n;
  HC_INLINE void set(const double ra[3], const double rb[3], double sb, const Vec3* const x[3]) {
    for (int k = 0; k < 3; ++k) r[k] = ra[k] + sb * rb[k];
    W = r[0] * *x[0] + r[1] * *x[1] + r[2] * *x[2];
    q = W.norm();
    n = (q > 0.0) ? Vec3(W / q) : Vec3::Zero();
  }
  // Rate of the length: n . W' (eq. 6, with W' from eq. 5)
  HC_INLINE double rate(const Vec3* const v[3]) const {
    return n.dot(r[0] * *v[0] + r[1] * *v[1] + r[2] * *v[2]);
  }
  Vec3 wdot(const Vec3* const v[3]) const { return r[0] * *v[0] + r[1] * *v[1] + r[2] * *v[2]; }
  // (I - n n^T) / q : the second derivative of |W| with respect to W. Each entry is one fused
  // multiply-add, written out so that its rounding does not depend on how the compiler inlines
  // and contracts the expression at each use.
  HC_INLINE Mat3 projector_over_length() const {
    if (q <= 0.0) return Mat3::Zero();
    Mat3 p;
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 3; ++i) p(i, j) = std::fma(-n[i], n[j], i == j ? 1.0 : 0.0) / q;
    return p;
  }
};

// Eq. 3 for U and V and the two diagonals S = U + V, D = U - V used by eq. 4.
struct Fibres {
  Fibre u, v, s, d;
  HC_INLINE void set(const ElementRest& e, const Vec3* const x[3]) {
    u.set(e.ru, e.rv, 0.0, x);
    v.set(e.rv, e.ru, 0.0, x);
    s.set(e.ru, e.rv, 1.0, x);
    d.set(e.ru, e.rv, -1.0, x);
  }
  // d eps_uv / dU and d eps_uv / dV: with them g_uv_k = ru_k a + rv_k b.
  HC_INLINE Vec3 shear_a() const { return (s.n - d.n) * kInvSqrt2; }
  HC_INLINE Vec3 shear_b() const { return (s.n + d.n) * kInvSqrt2; }
};

// The stresses of the three strains: the laws' tangents, and the total (elastic + viscous)
// stress that the forces and the geometric stiffness use.
struct Stresses {
  double s_uu, k_uu, s_vv, k_vv, s_uv, k_uv;  // elastic stress and tangent
  double t_uu, t_vv, t_uv;                    // total stress
};

// Eq. 4 strains through the material laws, and the element's elastic energy.
HC_INLINE Stresses elastic_stresses(const Fibres& F, const Material& m, double A,
                                    ElementEval& out) {
  Strains& eps = out.eps;
  eps.uu = F.u.q - 1.0;
  eps.vv = F.v.q - 1.0;
  eps.uv = (F.s.q - F.d.q) * kInvSqrt2;
  Stresses st;
  m.weft.evaluate(eps.uu, st.s_uu, st.k_uu);
  m.warp.evaluate(eps.vv, st.s_vv, st.k_vv);
  m.shear.evaluate(eps.uv, st.s_uv, st.k_uv);
  out.energy = A * (m.weft.energy(eps.uu) + m.warp.energy(eps.vv) + m.shear.energy(eps.uv));
  return st;
}

// Eq. 6 strain rates and the viscous stresses they add (skipped entirely for purely elastic
// materials).
HC_INLINE void total_stresses(const Fibres& F, const Material& m, const Vec3* const vel[3],
                              bool viscous, Stresses& st, ElementEval& out) {
  double sv_uu = 0.0, sv_vv = 0.0, sv_uv = 0.0;
  out.eps_rate = Strains{};
  if (viscous) {
    out.eps_rate.uu = F.u.rate(vel);
    out.eps_rate.vv = F.v.rate(vel);
    out.eps_rate.uv = (F.s.rate(vel) - F.d.rate(vel)) * kInvSqrt2;
    sv_uu = m.weft.viscosity * out.eps_rate.uu;
    sv_vv = m.warp.viscosity * out.eps_rate.vv;
    sv_uv = m.shear.viscosity * out.eps_rate.uv;
  }
  st.t_uu = st.s_uu + sv_uu;
  st.t_vv = st.s_vv + sv_vv;
  st.t_uv = st.s_uv + sv_uv;
}

// Gradient of each strain with respect to vertex k:
//   d eps_uu / d x_k = ru_k n_U,   d eps_vv / d x_k = rv_k n_V,
//   d eps_uv / d x_k = (rs_k n_S - rd_k n_D) / sqrt(2)   (g_uv, kept for the damping).
// F_k = -A sum sigma d eps / d x_k; for small shear this is eq. 7.
HC_INLINE void forces(const Fibres& F, double A, const Stresses& st, Vec3 g_uv[3],
                      ElementEval& out) {
  for (int k = 0; k < 3; ++k) {
    g_uv[k] = (F.s.r[k] * F.s.n - F.d.r[k] * F.d.n) * kInvSqrt2;
    out.f[k] = -A * (st.t_uu * F.u.r[k] * F.u.n + st.t_vv * F.v.r[k] * F.v.n + st.t_uv * g_uv[k]);
  }
}

// Hessian of the energy in factored form (P, Q, W of ElementEval): material part (tangent x
// gradient outer products) and geometric part (stress x second derivative of the fibre
// lengths). The geometric coefficient uses the total stress, so the symmetric part of the
// viscous position-derivative is included too. With rs = ru + rv, rd = ru - rv and
// g_uv = ru a + rv b, every block is
//   H_kl = ru_k ru_l P + rv_k rv_l Q + ru_k rv_l W + rv_k ru_l W^T
// which costs four scaled 3x3 additions per block instead of one per fibre and term.
HC_INLINE void stiffness_factors(const Fibres& F, double A, const Stresses& st, bool spd,
                                 ElementEval& out) {
  auto clamp = [spd](double c) { return (spd && c < 0.0) ? 0.0 : c; };
  const double ku = clamp(st.k_uu), kv = clamp(st.k_vv), ks = clamp(st.k_uv);
  const double gu = clamp(st.t_uu), gv = clamp(st.t_vv);
  // Shear: +t_uv on the S diagonal, -t_uv on the D diagonal; one of the two is negative.
  const double gs = clamp(st.t_uv * kInvSqrt2), gd = clamp(-st.t_uv * kInvSqrt2);
  const Mat3 Ms = A * gs * F.s.projector_over_length();
  const Mat3 Md = A * gd * F.d.projector_over_length();
  const Vec3 a = F.shear_a(), b = F.shear_b();
  const double Ak = A * ks;
  const Mat3 Msd = Ms + Md;
  out.P = A * (ku * F.u.n * F.u.n.transpose() + gu * F.u.projector_over_length()) + Msd +
          Ak * a * a.transpose();
  out.Q = A * (kv * F.v.n * F.v.n.transpose() + gv * F.v.projector_over_length()) + Msd +
          Ak * b * b.transpose();
  out.W = Ms - Md + Ak * a * b.transpose();
}

// Damping: -dF/dv = A sum eta grad(eps) grad(eps)^T (eq. 6 is linear in velocity), factored
// as H: C_kl = ru_k ru_l Pc + rv_k rv_l Qc + ru_k rv_l Wc + rv_k ru_l Wc^T.
HC_INLINE void damping_factors(const Fibres& F, double A, const Material& m, ElementEval& out) {
  const double cu = A * m.weft.viscosity, cv = A * m.warp.viscosity, cs = A * m.shear.viscosity;
  const Vec3 a = F.shear_a(), b = F.shear_b();
  out.Pc = cu * F.u.n * F.u.n.transpose() + cs * a * a.transpose();
  out.Qc = cv * F.v.n * F.v.n.transpose() + cs * b * b.transpose();
  out.Wc = cs * a * b.transpose();
}

// The 3x3 blocks of a factored Jacobian (k <= l formed, (l, k) its transpose).
HC_INLINE void expand_blocks(Mat3 blk[3][3], const double* ru, const double* rv, const Mat3& P,
                             const Mat3& Q, const Mat3& W) {
  for (int k = 0; k < 3; ++k) {
    for (int l = k; l < 3; ++l) {
      combine(blk[k][l], ru[k] * ru[l], P, rv[k] * rv[l], Q, ru[k] * rv[l], W, rv[k] * ru[l]);
      if (l != k) blk[l][k] = blk[k][l].transpose();
    }
  }
}

// The non-symmetric viscous part of -dF/dP: -dF_k/dx_l also holds
// A eta grad_k(eps) (d eps'/d x_l)^T, with d eps'/d x_l = r_l (I - n n^T) W' / q per fibre.
HC_INLINE void add_viscous_nonsymmetric(const Fibres& F, double A, const Material& m,
                                        const Vec3* const vel[3], const Vec3 g_uv[3],
                                        ElementEval& out) {
  const double cu = A * m.weft.viscosity, cv = A * m.warp.viscosity, cs = A * m.shear.viscosity;
  const Vec3 du = F.u.projector_over_length() * F.u.wdot(vel);
  const Vec3 dv = F.v.projector_over_length() * F.v.wdot(vel);
  const Vec3 ds = F.s.projector_over_length() * F.s.wdot(vel);
  const Vec3 dd = F.d.projector_over_length() * F.d.wdot(vel);
  for (int k = 0; k < 3; ++k) {
    for (int l = 0; l < 3; ++l) {
      const Vec3 grad_rate_uv = (F.s.r[l] * ds - F.d.r[l] * dd) * kInvSqrt2;
      out.H[k][l] += cu * F.u.r[k] * F.u.n * (F.u.r[l] * du).transpose() +
                     cv * F.v.r[k] * F.v.n * (F.v.r[l] * dv).transpose() +
                     cs * g_uv[k] * grad_rate_uv.transpose();
    }
  }
}

HC_INLINE void zero_damping(bool blocks, ElementEval& out) {
  out.Pc.setZero();
  out.Qc.setZero();
  out.Wc.setZero();
  for (int k = 0; k < 3 && blocks; ++k)
    for (int l = 0; l < 3; ++l) out.C[k][l].setZero();
}

}  // namespace

void evaluate_element(const ElementRest& e, const Material& m, const Vec3* const x[3],
                      const Vec3* const vel[3], const EvalRequest& req, ElementEval& out) {
  const double A = e.area;
  Fibres F;
  F.set(e, x);
  const bool viscous = m.viscous() && vel != nullptr;
  Stresses st = elastic_stresses(F, m, A, out);
  total_stresses(F, m, vel, viscous, st, out);
  Vec3 g_uv[3];
  forces(F, A, st, g_uv, out);
  if (!req.hessian) return;

  stiffness_factors(F, A, st, req.mode == JacobianMode::Spd, out);
  if (req.blocks) expand_blocks(out.H, F.u.r, F.v.r, out.P, out.Q, out.W);
  if (viscous) {
    damping_factors(F, A, m, out);
    if (req.blocks) expand_blocks(out.C, F.u.r, F.v.r, out.Pc, out.Qc, out.Wc);
    if (req.viscous_nonsymmetric) add_viscous_nonsymmetric(F, A, m, vel, g_uv, out);
  } else {
    zero_damping(req.blocks, out);
  }
}

void combine_blocks(Mat3& out, double c1, const Mat3& P, double c2, const Mat3& Q, double c3,
                    const Mat3& W, double c4) {
  combine(out, c1, P, c2, Q, c3, W, c4);
}

void element_forces_eq7(const ElementRest& e, const Material& m, const Vec3& xa, const Vec3& xb,
                        const Vec3& xc, Vec3 f[3]) {
  const Vec3 U = e.ru[0] * xa + e.ru[1] * xb + e.ru[2] * xc;
  const Vec3 V = e.rv[0] * xa + e.rv[1] * xb + e.rv[2] * xc;
  const Strains s = element_strains(e, xa, xb, xc);
  const double suu = m.weft.stress(s.uu), svv = m.warp.stress(s.vv), suv = m.shear.stress(s.uv);
  const Vec3 Un = U.normalized(), Vn = V.normalized();
  // Eq. 7, with d/2 taken as the (positive) rest area
  for (int k = 0; k < 3; ++k) {
    f[k] = -e.area * ((e.ru[k] * suu + e.rv[k] * suv) * Un + (e.ru[k] * suv + e.rv[k] * svv) * Vn);
  }
}

}  // namespace hapticloth::cloth
