// Static equilibrium of a cloth with prescribed (pinned) vertices: Newton's method on the
// elastic + gravitational energy, used by quasi-static tests such as the simulated Kawabata
// tests. No threads, no I/O.
#pragma once

#include <memory>

#include "cloth/integrator.hpp"

namespace hapticloth::cloth {

struct StaticOptions {
  double force_tolerance = 1e-9;  ///< converged when every free vertex's net force is below (N)
  int max_iterations = 100;
  /// The Newton matrix is H + M / h^2 (the system of eq. 9 with v = 0 and step h, divided by
  /// h^2): a tiny mass term keeps it definite where the membrane has no stiffness
  /// (out of plane of a flat sheet). It changes the path, not the equilibrium.
  double regularization_step = 1.0;  ///< h, s
};

struct StaticResult {
  bool converged = false;
  int iterations = 0;
  double residual = 0.0;  ///< largest net force on a free vertex at the end, N
};

class StaticSolver {
 public:
  /// The model must outlive the solver. Uses CHOLMOD for the Newton systems.
  StaticSolver(const ClothModel& model, const Vec3& gravity);

  /// Moves the free vertices of s to equilibrium; pinned vertices stay where s has them.
  /// Velocities are set to zero. Backtracking line search on the energy.
  StaticResult solve(ClothState& s, const StaticOptions& opt = {});

  /// Net force (elastic + gravity + external) on every vertex at s, N. On pinned vertices the
  /// negative of this is the reaction force the pin supplies.
  void net_forces(const ClothState& s, std::vector<Vec3>& f) const;

  std::vector<Vec3>& external_forces() { return f_ext_; }

 private:
  double energy(const ClothState& s) const;

  const ClothModel& model_;
  Vec3 gravity_;
  Integrator integ_;
  std::unique_ptr<LinearSolver> chol_;
  std::vector<Vec3> f_ext_, f_;
  ClothState trial_;
  Eigen::VectorXd dx_;
};

}  // namespace hapticloth::cloth
