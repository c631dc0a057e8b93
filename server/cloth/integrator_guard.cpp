// The Integrator's blow-up guard: the energy a step creates, per step and summed over a slow
// blow-up, against what the external forces did.
#include "cloth/integrator.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <numeric>
#include <stdexcept>
#include <string>

namespace hapticloth::cloth {

// |h M g| over the free vertices, N s: the right-hand side of eq. 9 for a cloth that starts to
// fall. The solves of a step stop at the solver's tolerance of the larger of this and their
// right-hand side. A cloth at rest has a right-hand side about a thousandth of this, and
// relative to that alone its solve would resolve forces a millionth of its weight. The residual
// so allowed is tolerance |g| |m| (2-norm over the vertices) as a force, far under the
// fingertip forces (docs/performance.md, "The script's step, and a cloth at rest solved to its
// weight's scale"). A cloth without gravity keeps the relative test.
double Integrator::weight_impulse(double h) const { return h * cfg_.gravity.norm() * free_mass_norm_; }

// A slow blow-up gains a fraction of the energy on every step, which the per-step test
// (energy_explosion, relative to the current energy) never sees. So the total energy at the start
// of this step (kinetic, elastic, gravitational: from the assembly) is compared with the previous
// step's plus the external work done in it, and the energy created is summed with a 0.1 s memory
// (a stable step creates none on a linear problem; the one linearized solve per step of a
// stiffening law creates some at large steps, a few times the floor: docs/scenes.md, 'The
// slow blow-up test'); past 10x the energy floor it is an explosion (hapticloth-bench
// stability: alpha 0.5 with a stiff material).
bool Integrator::slow_blow_up(double h) {
  if (!have_prev_energy_) return false;
  const double gain = energy_old_ - prev_energy_ - last_work_;
  const double excess = excess_energy_ * std::exp(-h / 0.1) + std::max(0.0, gain);
  if (excess > 10.0 * cfg_.explosion_ratio * energy_floor_) {
    ++events_.energy_explosions;
    blown_up_ = true;
    return true;
  }
  pending_excess_ = excess;  // kept when the step is accepted
  return false;
}

// Energy explosion: the step created far more energy than the external forces supplied (their
// work over the step goes to `work`). The elastic energy is >= 0 (Psi >= 0 for laws through the
// origin), so kinetic + gravitational energy is a lower bound of the new total and no second
// pass over the elements is needed: a blow-up always shows in the velocities. Counted.
bool Integrator::energy_explosion(const ClothState& s, double& work) {
  double ke = 0.0, eg = 0.0;
  work = 0.0;
  for (int i = 0; i < model_.num_vertices(); ++i) {
    if (model_.free_index[i] < 0) continue;
    ke += 0.5 * model_.mass[i] * vn_[i].squaredNorm();
    eg -= model_.mass[i] * cfg_.gravity.dot(xn_[i]);
    work += f_ext_[i].dot(xn_[i] - s.x[i]);
  }
  work += contact_work(s);
  const double e_new_lower = ke + eg;
  if (!std::isfinite(e_new_lower)) {
    ++events_.non_finite;
    return true;
  }
  const double gain = e_new_lower - energy_old_ - work;
  if (gain > cfg_.explosion_ratio * energy_scale_) {
    ++events_.energy_explosions;
    return true;
  }
  return false;
}

}  // namespace hapticloth::cloth
