// One fingertip's tactile output, tick by tick, from where on the fabric it is (the paper's
// tactile half: HAPTEX drove a 6 x 4 pin array per fingertip, 20-400 Hz): a vibration block and
// a pin frame.
//
// The fingertip's place is tracked in the cloth's material coordinates (u along the weft, v
// along the warp), so a stroke that drags the cloth along moves little over its surface and
// feels little texture. The skin touching the cloth is held to the fingertip's bone by a
// tangential spring k_s, and the cloth's friction coefficient mu(u, v) varies over the weave
// (cloth::Surface): the skin sticks while k_s |bone - skin| <= mu(skin) f_n, and slips forward
// to the nearest place where the spring force is back on the friction limit. Where mu rises
// faster along the path than k_s / f_n, that place jumps ahead: stick-slip.
//
// The vibration is the skin's displacement, m, sampled `rate` times a second:
//   s(t) = g(f_n) e(v) { h(skin(t)) + HP[ (k_s |bone - skin| - MIU f_n) / k_s ] }
// the surface height under the skin plus its tangential stretch about the mean friction's,
// the stretch through a first-order high-pass HP at `stretch_highpass` Hz: the stretch a stick
// holds (up to MIU f_n / k_s, 0.2 mm in a 1.5 N pinch) changes as slowly as the grip does and
// is no vibration, and the display drives the receptors from 20 Hz up (HAPTEX: 20-400 Hz). A
// slide's onset, where the stretch builds up, gives a pulse of the filter's time constant, 8 ms. A
// surface of spatial period lambda crossed at speed v gives the frequency v / lambda, and the
// signal's spectrum is the surface's spatial spectrum with wavenumber k mapped to v k. The
// force gain g(f_n) = min(f_n / full_force, 1): the skin follows the yarns more fully as it is
// pressed harder, until it wraps them. The speed envelope e(v) = min(v / full_speed, 1) makes
// a still fingertip's output exactly zero (the receptors that feel texture answer to change),
// as it is off contact.
#pragma once

#include <array>
#include <complex>

#include "cloth/surface.hpp"
#include "hal/tactile.hpp"

namespace hapticloth::tactile {

constexpr int kMaxBlock = devices::kMaxTactileSamples;  ///< vibration samples per tick: 16 kHz at 1 kHz
constexpr int kMaxPins = devices::kMaxPins;

struct TactileParams {
  int rate = 4000;                 ///< Hz: vibration samples a second (a multiple of the tick rate)
  double skin_stiffness = 1500.0;  ///< N/m: the fingerpad's tangential stiffness, k_s
  double full_force = 0.5;         ///< N: the normal force at which the skin follows the surface fully
  double full_speed = 0.005;       ///< m/s: sliding speed at which the texture is felt fully
  double stretch_highpass = 20.0;  ///< Hz: the stretch's high-pass corner (first order): the display band's floor
  int pin_rows = 6, pin_cols = 4;  ///< the pin array (HAPTEX: 6 x 4)
  double pin_pitch = 0.002;        ///< m between pins
  void validate() const;           ///< throws std::invalid_argument naming the field
  /// HP(f), the stretch's high-pass at f Hz: j (f / fc) / (1 + j (f / fc)).
  std::complex<double> stretch_highpass_response(double f) const {
    const std::complex<double> jw(0.0, f / stretch_highpass);
    return jw / (1.0 + jw);
  }
};

/// Where the fingertip is on the cloth at the end of a tick.
struct TactileInput {
  bool in_contact = false;
  double normal_force = 0.0;   ///< N
  double u = 0.0, v = 0.0;     ///< the contact's material coordinates, m
  double patch_radius = 0.0;   ///< m: the contact patch's radius
};

/// The device's frame (vibration block, pins: hal/tactile.hpp) and the skin's state.
struct TactileOutput : devices::TactileFrame {
  double tangential_force = 0.0;        ///< N, the skin spring's force at the end of the tick
  bool slipping = false;                ///< the skin slipped in this tick
};

class TactileChannel {
 public:
  TactileChannel(const cloth::Surface& surface, const TactileParams& p, double tick_s);

  /// One tick: the vibration block and the pin frame. No allocation.
  void tick(const TactileInput& in, TactileOutput& out) noexcept;

 private:
  void release() noexcept;
  double slide_skin(double bu, double bv, double fn) noexcept;
  void fill_pins(const TactileInput& in, TactileOutput& out) const noexcept;

  const cloth::Surface& surface_;
  TactileParams p_;
  int block_;
  double tick_s_;
  bool touching_ = false;
  double bone_u_ = 0.0, bone_v_ = 0.0;  // the fingertip's material position at the last tick
  double skin_u_ = 0.0, skin_v_ = 0.0;  // where the skin touches the cloth
  double step_;                         // m: the search step of a slip
  double hp_a_;                         // the high-pass's coefficient RC / (RC + dt)
  double hp_in_ = 0.0, hp_out_ = 0.0;   // its last input and output
};

}  // namespace hapticloth::tactile
