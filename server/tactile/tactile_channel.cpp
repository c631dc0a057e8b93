#include "tactile/tactile_channel.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace hapticloth::tactile {

namespace {
// A slip's search for where the skin comes to rest takes at most this many steps; a jump
// further than that (the fingertip carried centimetres in a tick) puts the skin where the
// spring holds it against the friction at the fingertip's place.
constexpr int kMaxSlipSteps = 256;
}  // namespace

void TactileParams::validate() const {
  auto fail = [](const std::string& what) { throw std::invalid_argument("tactile: " + what); };
  if (rate < 1000 || rate > 1000 * kMaxBlock || rate % 1000 != 0)
    fail("rate must be a multiple of 1000 Hz in [1000, " + std::to_string(1000 * kMaxBlock) + "], not " + std::to_string(rate));
  if (!(skin_stiffness > 0.0)) fail("skin_stiffness must be > 0 N/m");
  if (!(full_force > 0.0)) fail("full_force must be > 0 N");
  if (!(full_speed > 0.0)) fail("full_speed must be > 0 m/s");
  if (!(stretch_highpass > 0.0) || !(stretch_highpass < 0.05 * rate)) fail("stretch_highpass must be in (0, rate / 20) Hz");
  if (pin_rows < 0 || pin_cols < 0 || pin_rows * pin_cols > kMaxPins)
    fail("pin_rows x pin_cols must be in [0, " + std::to_string(kMaxPins) + "]");
  if (!(pin_pitch > 0.0)) fail("pin_pitch must be > 0 m");
}

TactileChannel::TactileChannel(const cloth::Surface& surface, const TactileParams& p, double tick_s)
    : surface_(surface), p_(p), tick_s_(tick_s) {
  p_.validate();
  if (!(tick_s > 0.0)) throw std::invalid_argument("tactile: tick must be > 0 s");
  block_ = static_cast<int>(std::lround(p_.rate * tick_s));
  if (block_ < 1 || block_ > kMaxBlock)
    throw std::invalid_argument("tactile: " + std::to_string(p_.rate) + " Hz gives " + std::to_string(block_) +
                                " samples a tick, outside [1, " + std::to_string(kMaxBlock) + "]");
  const double rc = 1.0 / (2.0 * 3.14159265358979323846 * p_.stretch_highpass), dt = 1.0 / p_.rate;
  hp_a_ = rc / (rc + dt);
  step_ = 1e-5;
  for (const cloth::SurfaceProfile* s : {&surface_.weft, &surface_.warp})
    if (!s->empty()) step_ = std::min(step_, s->spacing());
}

void TactileChannel::release() noexcept { touching_ = false; }

// The skin's new place for the fingertip's bone at (bu, bv): it sticks while the spring's force
// is within mu f_n, else it slips along the stretch to the first place where it is back within
// (a jump past a rise of mu is a slip event). Returns the spring's force, N.
double TactileChannel::slide_skin(double bu, double bv, double fn) noexcept {
  const double k = p_.skin_stiffness, mean_stretch = surface_.miu * fn / k;
  const double du = bu - skin_u_, dv = bv - skin_v_, r = std::hypot(du, dv);
  auto mu = [&](double a) {
    return std::max(surface_.friction(skin_u_ + a * du / r, skin_v_ + a * dv / r), 0.0);
  };
  if (r <= 0.0 || k * r <= mu(0.0) * fn) return k * r;
  auto excess = [&](double a) { return k * (r - a) - mu(a) * fn; };  // > 0: still slipping
  double a = 0.0, ga = excess(0.0);
  for (int i = 0; i < kMaxSlipSteps && a < r; ++i) {
    const double b = std::min(a + step_, r), gb = excess(b);
    if (gb <= 0.0) {
      a += (b - a) * ga / (ga - gb);  // where the excess crosses zero, linearly
      ga = 0.0;
      break;
    }
    a = b;
    ga = gb;
  }
  if (ga > 0.0 && a < r) a = std::max(r - mu(r) * fn / k, a);  // a jump beyond the search
  skin_u_ += a * du / r;
  skin_v_ += a * dv / r;
  return k * (r - a);
}

void TactileChannel::fill_pins(const TactileInput& in, TactileOutput& out) const noexcept {
  out.rows = p_.pin_rows;
  out.cols = p_.pin_cols;
  const double r2 = in.patch_radius * in.patch_radius;
  for (int i = 0; i < p_.pin_rows; ++i)
    for (int j = 0; j < p_.pin_cols; ++j) {
      const double du = (j - 0.5 * (p_.pin_cols - 1)) * p_.pin_pitch;
      const double dv = (i - 0.5 * (p_.pin_rows - 1)) * p_.pin_pitch;
      const bool under = touching_ && du * du + dv * dv <= r2;
      out.pins[static_cast<size_t>(i * p_.pin_cols + j)] =
          under ? static_cast<float>(surface_.height(skin_u_ + du, skin_v_ + dv)) : 0.0f;
    }
}

void TactileChannel::tick(const TactileInput& in, TactileOutput& out) noexcept {
  out.samples = block_;
  out.slipping = false;
  out.tangential_force = 0.0;
  const double fn = in.normal_force;
  if (!in.in_contact || !(fn > 0.0) || !std::isfinite(in.u) || !std::isfinite(in.v)) {
    release();
    std::fill(out.vibration.begin(), out.vibration.begin() + block_, 0.0f);
    fill_pins(in, out);
    return;
  }
  const double k = p_.skin_stiffness, mean_stretch = surface_.miu * fn / k;
  if (!touching_) {  // first touch: no motion yet, the high-pass starts settled
    touching_ = true;
    bone_u_ = skin_u_ = in.u;
    bone_v_ = skin_v_ = in.v;
    hp_in_ = -mean_stretch;
    hp_out_ = 0.0;
  }
  const double u0 = bone_u_, v0 = bone_v_;
  const double speed = std::hypot(in.u - u0, in.v - v0) / tick_s_;
  const double gain = std::min(fn / p_.full_force, 1.0) * std::min(speed / p_.full_speed, 1.0);
  for (int i = 0; i < block_; ++i) {
    const double t = static_cast<double>(i + 1) / block_;
    const double su = skin_u_, sv = skin_v_;
    const double ft = slide_skin(u0 + t * (in.u - u0), v0 + t * (in.v - v0), fn);
    out.slipping = out.slipping || su != skin_u_ || sv != skin_v_;
    out.tangential_force = ft;
    const double stretch = ft / k - mean_stretch;
    hp_out_ = hp_a_ * (hp_out_ + stretch - hp_in_);
    hp_in_ = stretch;
    out.vibration[static_cast<size_t>(i)] = static_cast<float>(gain * (surface_.height(skin_u_, skin_v_) + hp_out_));
  }
  bone_u_ = in.u;
  bone_v_ = in.v;
  fill_pins(in, out);
}

}  // namespace hapticloth::tactile
