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
  // Rate of the length: n . W' (eq. 6)
  HC_INLINE double rate(const Vec3* const v[3]) const {
    return n.dot(r[0] * *v[0] + r[1] * *v[1] + r[2] * *v[2]);
  }
  Vec3 wdot(const Vec3* const v[3]) const { return r[0] * *v[0] + r[1] * *v[1] + r[2] * *v[2]; }
  // (I - n n^T) / q : the second derivative of |W| with respect to W
  HC_INLINE Mat3 projector_over_length() const {
    if (q <= 0.0) return Mat3::Zero();
    return (Mat3::Identity() - n * n.transpose()) / q;
  }
};

}  // namespace

void evaluate_element(const ElementRest& e, const Material& m, const Vec3* const x[3],
                      const Vec3* const vel[3], const EvalRequest& req, ElementEval& out) {
  const double A = e.area;
  // Eq. 3 for U and V and the two diagonals S = U + V, D = U - V used by eq. 4.
  Fibre fu, fv, fs, fd;
  fu.set(e.ru, e.rv, 0.0, x);
  fv.set(e.rv, e.ru, 0.0, x);
  fs.set(e.ru, e.rv, 1.0, x);
  fd.set(e.ru, e.rv, -1.0, x);

  // Eq. 4
  Strains& eps = out.eps;
  eps.uu = fu.q - 1.0;
  eps.vv = fv.q - 1.0;
  eps.uv = (fs.q - fd.q) * kInvSqrt2;

  double s_uu, k_uu, s_vv, k_vv, s_uv, k_uv;
  m.weft.evaluate(eps.uu, s_uu, k_uu);
  m.warp.evaluate(eps.vv, s_vv, k_vv);
  m.shear.evaluate(eps.uv, s_uv, k_uv);
  out.energy = A * (m.weft.energy(eps.uu) + m.warp.energy(eps.vv) + m.shear.energy(eps.uv));

  // Eq. 6 and the viscous stresses (skipped entirely for purely elastic materials).
  const bool viscous = m.viscous() && vel != nullptr;
  double sv_uu = 0.0, sv_vv = 0.0, sv_uv = 0.0;
  out.eps_rate = Strains{};
  if (viscous) {
    out.eps_rate.uu = fu.rate(vel);
    out.eps_rate.vv = fv.rate(vel);
    out.eps_rate.uv = (fs.rate(vel) - fd.rate(vel)) * kInvSqrt2;
    sv_uu = m.weft.viscosity * out.eps_rate.uu;
    sv_vv = m.warp.viscosity * out.eps_rate.vv;
    sv_uv = m.shear.viscosity * out.eps_rate.uv;
  }
  const double t_uu = s_uu + sv_uu, t_vv = s_vv + sv_vv, t_uv = s_uv + sv_uv;

  // Gradient of each strain with respect to vertex k:
  //   d eps_uu / d x_k = ru_k n_U,   d eps_vv / d x_k = rv_k n_V,
  //   d eps_uv / d x_k = (rs_k n_S - rd_k n_D) / sqrt(2).
  // F_k = -A sum sigma d eps / d x_k; for small shear this is eq. 7.
  Vec3 g_uv[3];
  for (int k = 0; k < 3; ++k) {
    g_uv[k] = (fs.r[k] * fs.n - fd.r[k] * fd.n) * kInvSqrt2;
    out.f[k] = -A * (t_uu * fu.r[k] * fu.n + t_vv * fv.r[k] * fv.n + t_uv * g_uv[k]);
  }
  if (!req.hessian) return;

  // Hessian of the energy: material part (tangent x gradient outer products) and geometric part
  // (stress x second derivative of the fibre lengths). The geometric coefficient uses the total
  // stress, so the symmetric part of the viscous position-derivative is included too.
  const bool spd = req.mode == JacobianMode::Spd;
  auto clamp = [spd](double c) { return (spd && c < 0.0) ? 0.0 : c; };
  const double ku = clamp(k_uu), kv = clamp(k_vv), ks = clamp(k_uv);
  const double gu = clamp(t_uu), gv = clamp(t_vv);
  // Shear: +t_uv on the S diagonal, -t_uv on the D diagonal; one of the two is negative.
  const double gs = clamp(t_uv * kInvSqrt2), gd = clamp(-t_uv * kInvSqrt2);

  // With rs = ru + rv, rd = ru - rv and g_uv = ru a + rv b (a, b below), every block is
  //   H_kl = ru_k ru_l P + rv_k rv_l Q + ru_k rv_l W + rv_k ru_l W^T
  // which costs four scaled 3x3 additions per block instead of one per fibre and term.
  const Mat3 Ms = A * gs * fs.projector_over_length();
  const Mat3 Md = A * gd * fd.projector_over_length();
  const Vec3 a = (fs.n - fd.n) * kInvSqrt2, b = (fs.n + fd.n) * kInvSqrt2;
  const double Ak = A * ks;
  const Mat3 Msd = Ms + Md;
  Mat3& P = out.P;
  Mat3& Q = out.Q;
  Mat3& W = out.W;
  P = A * (ku * fu.n * fu.n.transpose() + gu * fu.projector_over_length()) + Msd +
      Ak * a * a.transpose();
  Q = A * (kv * fv.n * fv.n.transpose() + gv * fv.projector_over_length()) + Msd +
      Ak * b * b.transpose();
  W = Ms - Md + Ak * a * b.transpose();
  const double* ru = fu.r;
  const double* rv = fv.r;
  if (req.blocks) {
    for (int k = 0; k < 3; ++k) {
      for (int l = k; l < 3; ++l) {
        combine(out.H[k][l], ru[k] * ru[l], P, rv[k] * rv[l], Q, ru[k] * rv[l], W, rv[k] * ru[l]);
        if (l != k) out.H[l][k] = out.H[k][l].transpose();
      }
    }
  }

  if (viscous) {
    // Damping: -dF/dv = A sum eta grad(eps) grad(eps)^T (eq. 6 is linear in velocity).
    const double cu = A * m.weft.viscosity, cv = A * m.warp.viscosity, cs = A * m.shear.viscosity;
    // Same factorization as H: C_kl = ru_k ru_l Pc + rv_k rv_l Qc + ru_k rv_l Wc + rv_k ru_l Wc^T
    const Vec3 a = (fs.n - fd.n) * kInvSqrt2, b = (fs.n + fd.n) * kInvSqrt2;
    Mat3& Pc = out.Pc;
    Mat3& Qc = out.Qc;
    Mat3& Wc = out.Wc;
    Pc = cu * fu.n * fu.n.transpose() + cs * a * a.transpose();
    Qc = cv * fv.n * fv.n.transpose() + cs * b * b.transpose();
    Wc = cs * a * b.transpose();
    for (int k = 0; k < 3 && req.blocks; ++k) {
      for (int l = k; l < 3; ++l) {
        combine(out.C[k][l], ru[k] * ru[l], Pc, rv[k] * rv[l], Qc, ru[k] * rv[l], Wc, rv[k] * ru[l]);
        if (l != k) out.C[l][k] = out.C[k][l].transpose();
      }
    }
    if (req.viscous_nonsymmetric) {
      // -dF_k/dx_l also holds A eta grad_k(eps) (d eps'/d x_l)^T, with
      // d eps'/d x_l = r_l (I - n n^T) W' / q per fibre.
      const Vec3 du = fu.projector_over_length() * fu.wdot(vel);
      const Vec3 dv = fv.projector_over_length() * fv.wdot(vel);
      const Vec3 ds = fs.projector_over_length() * fs.wdot(vel);
      const Vec3 dd = fd.projector_over_length() * fd.wdot(vel);
      for (int k = 0; k < 3; ++k) {
        for (int l = 0; l < 3; ++l) {
          const Vec3 grad_rate_uv = (fs.r[l] * ds - fd.r[l] * dd) * kInvSqrt2;
          out.H[k][l] += cu * fu.r[k] * fu.n * (fu.r[l] * du).transpose() +
                         cv * fv.r[k] * fv.n * (fv.r[l] * dv).transpose() +
                         cs * g_uv[k] * grad_rate_uv.transpose();
        }
      }
    }
  } else {
    out.Pc.setZero();
    out.Qc.setZero();
    out.Wc.setZero();
    for (int k = 0; k < 3 && req.blocks; ++k)
      for (int l = 0; l < 3; ++l) out.C[k][l].setZero();
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
