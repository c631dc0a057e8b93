// Time-domain passivity observer and controller (Hannaford and Ryu 2002) on each finger's
// virtual coupling: the spring-damper between the device's fingertip and the rendered proxy.
//
// A sampled coupling renders its force held over a tick. On time (T = 1 ms) the coupling's
// damper outweighs what the hold generates (Colgate's condition c > k T / 2: 1 > 0.4 N s/m at
// the defaults), but a tick that starts L late holds the force for T + L, and at L = 20 ms
// k (T + L) / 2 = 8.4 N s/m: the coupling can give the hand energy it never got. The observer
// measures it tick by tick with the measured interval, and the controller dissipates it.
//
// Observer (per finger, in the coupling's power convention): over the interval that ends at
// tick n, with F the force the user actually got (held), x the device's fingertip and p the
// proxy,
//   W_n = Fc . (p_n - p_n-1) - F . (x_n - x_n-1) - (U_n - U_n-1),   U = |Fs|^2 / (2 k)
// is the energy the coupling absorbed (the user's side gives -F . dx with F what the hand got,
// the proxy's side Fc . dp with Fc the coupling's own force; U is the spring's stored energy,
// from the spring's force Fs: the simulation solves the proxy against the fingertip of the
// tick before, so k |p - x|^2 / 2 with this tick's fingertip would be off by the tick's
// motion). Its sum,
// the reserve R, is >= 0 for a passive coupling. Beyond a small cap the reserve leaks away
// (kReserveCap, kReserveLeak), so that earlier dissipation cannot hide a later burst.
//
// Controller: while R < -1 uJ (kDeadband), a damper alpha v against the device's velocity,
// alpha = -R / (|v|^2 tau), at most max_force: the deficit is dissipated over tau
// (kDissipationTime, 20 ms) rather than in the next tick as in the original scheme, because a
// controller that pays it back in one tick is itself a force step, far larger than a tick's
// change of the stroke on time (docs/haptic-loop.md, 'The coupling is kept passive').
// Real-time safe: no allocation, no lock.
#pragma once

#include <array>
#include <cstdint>

#include "haptics/sim/handoff.hpp"

namespace hapticloth::haptics {

struct PassivityStats {
  std::uint64_t active_ticks = 0;   ///< ticks on which the controller added damping
  double dissipated_j = 0.0;        ///< energy the controller's damping asked to dissipate, J
  double deepest_deficit_j = 0.0;   ///< largest energy the coupling gave beyond passivity, J
};

class CouplingPassivity {
 public:
  /// `stiffness`: the coupling spring (N/m); `max_force`:
  /// the most the controller adds (N).
  CouplingPassivity(double stiffness, double max_force);

  /// One tick of finger f, `dt` (s) after the last: `applied` the force the user got over the interval that ends now
  /// (scene frame), `x` the device's fingertip now, `p` the proxy, `v` the device's velocity,
  /// `coupling` the coupling's force for this
  /// tick (without the controller's), `spring` its spring's part; `coupled` false while the coupling renders no force (out
  /// of contact: nothing is stored). Returns the controller's force for this tick (zero while
  /// the reserve is >= 0).
  Vec3 observe(int f, double dt, const Vec3& applied, const Vec3& x, const Vec3& p,
               const Vec3& v, const Vec3& coupling, const Vec3& spring, bool coupled) noexcept;
  /// Forget finger f's history (absent finger, reactivation).
  void reset(int f) noexcept;

  double reserve(int f) const { return fs_[f].reserve; }
  const PassivityStats& stats() const { return stats_; }

  /// Beyond this (J) the reserve leaks away with time constant kReserveLeak (s): only the
  /// dissipation of the last tens of ms may pay for energy given back, so earlier dissipation
  /// cannot hide a later burst.
  static constexpr double kReserveCap = 1e-4;
  static constexpr double kReserveLeak = 0.05;
  /// The controller dissipates a deficit over this long (s).
  static constexpr double kDissipationTime = 0.02;
  /// Deficits smaller than this (J) are left alone: on time the observer sees a few tenths of a
  /// microjoule at contact onsets (the main job's deepest deficit: docs/contact.md, 'Local
  /// refinement under the fingertips'), and damping them is force noise on hundreds of ticks for
  /// nothing a hand can feel.
  static constexpr double kDeadband = 1e-6;

 private:
  struct Finger {
    bool have = false;
    Vec3 x = Vec3::Zero(), p = Vec3::Zero();
    Vec3 coupling = Vec3::Zero();  // held over the interval that ends at the next tick
    double stored = 0.0;
    double reserve = 0.0;
  };
  double k_, max_force_;
  std::array<Finger, kMaxFingers> fs_{};
  PassivityStats stats_;
};

}  // namespace hapticloth::haptics
