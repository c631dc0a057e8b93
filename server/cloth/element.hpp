// The triangle particle-system element of section 3.3.2 (eqs. 2-7).
#pragma once

#include <Eigen/Core>

#include "cloth/material.hpp"

namespace hapticloth::cloth {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

/// Rest data of one triangle: vertex indices, the R coefficients of eq. 2 and the rest area.
struct ElementRest {
  int v[3] = {0, 0, 0};
  double ru[3] = {0, 0, 0};  ///< R_ua, R_ub, R_uc
  double rv[3] = {0, 0, 0};  ///< R_va, R_vb, R_vc
  double area = 0.0;         ///< |d| / 2, m^2
};

/// Eq. 2: R coefficients from the weave (u, v) coordinates of the three vertices, in metres.
/// Throws std::invalid_argument if the triangle is degenerate in weave space.
ElementRest make_element(int a, int b, int c, const double uv[3][2]);

/// In-plane strains of eq. 4 (and strain rates of eq. 6).
struct Strains {
  double uu = 0, vv = 0, uv = 0;
};

/// How the position Jacobian is formed for the system matrix.
enum class JacobianMode {
  Exact,  ///< the exact Hessian of the elastic energy (may be indefinite)
  Spd,    ///< geometric-stiffness parts with a negative coefficient and negative tangents are
          ///< left out (Choi and Ko 2002), so every element block is positive semi-definite
};

/// What one element contributes at the current state. Blocks are 3x3 between vertices k, l.
struct ElementEval {
  double energy = 0.0;  ///< A * (Psi_uu + Psi_vv + Psi_uv), J
  Strains eps;          ///< eq. 4
  Strains eps_rate;     ///< eq. 6 (zero when the material has no viscosity)
  Vec3 f[3];            ///< force on each vertex, N (elastic + viscous)
  Mat3 H[3][3];         ///< stiffness: -dF/dP (symmetric; see JacobianMode), N/m
  Mat3 C[3][3];         ///< damping: -dF/dP', N s/m (symmetric PSD)
  /// Factored form of the symmetric H (and of C with Pc, Qc, Wc): for vertices k, l
  ///   H_kl = ru_k ru_l P + rv_k rv_l Q + ru_k rv_l W + rv_k ru_l W^T
  /// (without the non-symmetric viscous part). Assembly works on this form directly.
  Mat3 P, Q, W, Pc, Qc, Wc;
};

/// Options of one evaluation.
struct EvalRequest {
  bool hessian = true;          ///< compute the Jacobians (factored form P, Q, W, Pc, Qc, Wc)
  bool blocks = true;           ///< also expand them into the 3x3 blocks H and C
  JacobianMode mode = JacobianMode::Spd;
  bool viscous_nonsymmetric = false;  ///< add the non-symmetric viscous part of -dF/dP
                                      ///< (exact Jacobian, for checks; not used in the solve)
};

/// Eq. 3-4: strains of an element at positions x.
Strains element_strains(const ElementRest& e, const Vec3& xa, const Vec3& xb, const Vec3& xc);

/// Elastic energy only (eq. 4 strains through the curves' Psi), J.
double element_energy(const ElementRest& e, const Material& m, const Vec3& xa, const Vec3& xb,
                      const Vec3& xc);

/// Forces as the exact negative gradient of the element energy plus viscous forces, and their
/// Jacobians. `vel` may be null when the material has no viscosity.
/// Allocation-free.
void evaluate_element(const ElementRest& e, const Material& m, const Vec3* const x[3],
                      const Vec3* const vel[3], const EvalRequest& req, ElementEval& out);

/// out = c1 P + c2 Q + c3 W + c4 W^T (the block formula of the factored Jacobians).
void combine_blocks(Mat3& out, double c1, const Mat3& P, double c2, const Mat3& Q, double c3,
                    const Mat3& W, double c4);

/// Eq. 7 as printed in the paper (the small-shear form of the energy gradient), elastic only.
void element_forces_eq7(const ElementRest& e, const Material& m, const Vec3& xa, const Vec3& xb,
                        const Vec3& xc, Vec3 f[3]);

}  // namespace hapticloth::cloth
