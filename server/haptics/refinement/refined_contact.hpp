// The fingertip pressed into the refined child mesh (paper 4.2.2): the compliance the global
// mesh cannot take.
//
// A linear element cannot take the dimple under a fingertip, w ~ F / (2 pi T) ln(r), whose
// shape changes on the scale of the contact patch: on a mesh of edge h it stands in for a
// dimple that stops at r ~ h instead of the patch radius a, so the global cloth is stiffer by
// the compliance ln(h / a) / (2 pi T) of the part it misses (docs/contact.md). The child mesh
// resolves that part. Its border follows the global cloth; each fingertip sphere in it is a
// rigid body pushed into it with the normal force the global step rendered, and the child is
// brought to static equilibrium (the sphere's displacement along its normal is an unknown
// beside the child's vertices). How much deeper the sphere then sits than the global proxy is
// the compliance the global mesh lacks, per unit force:
//
//     c = s / N,    s = depth in the child carrying N - depth in the global cloth carrying N
//
// measured in the child, not fitted. The global step puts it in series with the virtual
// coupling (FingertipContact::set_refined_compliance), so the device feels the refined
// model's force and the global cloth gets exactly that force (the proxy stays massless).
//
// The equilibrium minimizes, over the free child vertices x and the spheres' displacements s_f,
//   E = sum_e A_e Psi_e(x) (eqs. 3-5)  -  sum_i m_i g . x_i
//     + sum_f sum_i a_i kappa (d^2 / 2 + d^3 / (3 d_s))   (the contact law of FingertipContact,
//                                                          d the depth of vertex i in sphere f)
//     - sum_f N_f s_f,
// by Newton's method with the elements' positive semi-definite Jacobians and a backtracking
// line search on E. Frictionless: friction moves the contact tangentially, not deeper.
#pragma once

#include <Eigen/Dense>

#include <array>
#include <memory>
#include <vector>

#include "cloth/model.hpp"
#include "cloth/solver.hpp"
#include "haptics/sim/handoff.hpp"
#include "haptics/refinement/refined_mesh.hpp"

namespace hapticloth::haptics {

struct ChildLaw {
  double radius = 0.008;              ///< m, fingertip sphere
  double pressure_stiffness = 3e9;    ///< Pa/m, kappa
  double stiffening_depth = 0.25e-3;  ///< m, d_s
};

/// One fingertip in the child: its global proxy and the normal force it carries there.
struct ChildFinger {
  bool in = false;
  Vec3 centre = Vec3::Zero();  ///< the global proxy's centre, m
  Vec3 normal = Vec3::Zero();  ///< unit, from the cloth toward the fingertip
  double force = 0.0;          ///< N along `normal` (what the cloth pushes back with)
};

class RefinedContact {
 public:
  RefinedContact(RefinedMesh mesh, const cloth::Material& material, const Vec3& gravity,
                 const ChildLaw& law);

  /// Moves the held vertices to the global cloth, the free ones with them (keeping their own
  /// displacement from the interpolation, a warm start).
  void follow(const std::vector<Vec3>& global_x);
  /// Newton iterations toward equilibrium with these fingers (at most `iterations`). Returns
  /// the largest remaining net force on a free vertex or sphere, N.
  double settle(const std::array<ChildFinger, kMaxFingers>& fingers, int iterations);
  /// Finger f's extra depth s_f (m) along -normal beyond the global proxy.
  double extra_depth(int f) const { return s_[f]; }
  /// The child's net push on sphere f at the last settle, N (from the cloth toward the
  /// fingertip). The sphere is moved along the normal it was given alone, but a frictionless
  /// sphere in a smooth membrane is pushed along the membrane's own normal there, whatever the
  /// coarse facets' normal was: this is the direction the refined cloth pushes the fingertip.
  const Vec3& push(int f) const { return push_[f]; }

  const RefinedMesh& mesh() const { return mesh_; }
  const cloth::ClothModel& model() const { return model_; }
  const std::vector<Vec3>& positions() const { return x_; }

 private:
  double energy(const std::vector<Vec3>& x, const std::array<double, kMaxFingers>& s) const;
  double assemble(const std::vector<Vec3>& x, const std::array<double, kMaxFingers>& s);
  void build_pattern();
  bool newton_step();

  RefinedMesh mesh_;
  cloth::ClothModel model_;
  Vec3 gravity_;
  ChildLaw law_;
  std::vector<Vec3> x_, x_try_, placed_, placed_before_;
  std::array<double, kMaxFingers> s_{}, s_try_{};
  std::array<Vec3, kMaxFingers> push_{};
  std::array<ChildFinger, kMaxFingers> fing_{};
  cloth::SymCsr A_;  // the child's pattern (model_.pattern), solved with CHOLMOD
  std::unique_ptr<cloth::LinearSolver> chol_;
  // The Newton matrix [A B; B^T C] over (x, s): A over the free coordinates (its pattern fixed at
  // construction; offsets into its values per element block entry, -1 where a corner is held,
  // and per free vertex its diagonal block's), B and C dense (a sphere couples to the vertices
  // it touches). The s unknowns are eliminated by their Schur complement, so A's factor stays as
  // sparse as the mesh.
  std::vector<int> elem_at_, diag_at_;
  Eigen::MatrixXd B_, Y_;
  std::array<double, kMaxFingers> C_{}, gs_{};
  Eigen::VectorXd g_, dx_, y_;
  std::array<double, kMaxFingers> ds_{};
};

}  // namespace hapticloth::haptics
