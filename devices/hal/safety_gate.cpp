#include "hal/safety_gate.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace hapticloth::devices {

SafetyGate::SafetyGate(const DeviceInfo& info, const GateConfig& cfg)
    : fingers_(info.fingers), tactile_(info.tactile) {
  auto bad = [](const std::string& f) {
    throw std::invalid_argument("safety gate: " + f + " must be finite and > 0");
  };
  if (const std::string e = validate(info); !e.empty()) throw std::invalid_argument("safety gate: device " + e);
  if (!(cfg.max_force >= 0.0) || !std::isfinite(cfg.max_force)) bad("max_force");
  if (!(cfg.slew_rate > 0.0) || !std::isfinite(cfg.slew_rate)) bad("slew_rate");
  if (!(cfg.watchdog > 0.0) || !std::isfinite(cfg.watchdog)) bad("watchdog");
  if (!(cfg.ramp_time > 0.0) || !std::isfinite(cfg.ramp_time)) bad("ramp_time");
  max_force_ = cfg.max_force > 0.0 ? std::min(cfg.max_force, info.max_force) : info.max_force;
  slew_ = cfg.slew_rate;
  watchdog_ = cfg.watchdog;
  ramp_ = cfg.ramp_time;
  nominal_dt_ = 1.0 / info.nominal_rate;
  reset();
}

void SafetyGate::reset() {
  last_now_ = -1.0;
  gain_ = 0.0;
  stale_ = true;
  for (auto& p : prev_) p.setZero();
  for (auto& h : held_) h.setZero();
}

void SafetyGate::apply(double now, double state_time, const DeviceCommand& in,
                       DeviceCommand& out) noexcept {
  ++c_.commands;
  double dt = nominal_dt_;
  if (last_now_ >= 0.0 && std::isfinite(now)) dt = std::clamp(now - last_now_, 0.0, 0.1);
  last_now_ = now;

  // Watchdog.
  const bool stale = !fresh(now, state_time);
  if (stale && !stale_) ++c_.stale_events;
  stale_ = stale;
  if (stale) ++c_.stale_ticks;
  const double dg = dt / ramp_;
  gain_ = stale ? std::max(0.0, gain_ - dg) : std::min(1.0, gain_ + dg);

  std::uint32_t flags = stale ? kFlagStale : 0u;
  const double max_step = slew_ * dt;
  for (int i = 0; i < kMaxFingers; ++i) {
    Vec3 f = (i < fingers_) ? in.force[i] : Vec3::Zero();
    if (!f.allFinite()) {
      f.setZero();
      flags |= kFlagFault;
      ++c_.non_finite;
    }
    const double n = f.norm();
    if (n > max_force_) {
      f *= max_force_ / n;
      flags |= kFlagClamped;
      ++c_.clamped;
    }
    // Stale, the loop renders nothing (the fingertip's place is unknown): what fades out over
    // the ramp is the force last asked while the state was fresh, not the loop's zero.
    if (stale) f = held_[i];
    else held_[i] = f;
    f *= gain_;
    // Slew limit per component, so a step in force becomes a ramp.
    const Vec3 d = f - prev_[i];
    const double dm = d.cwiseAbs().maxCoeff();
    if (dm > max_step) {
      f = prev_[i] + d * (max_step / dm);
      ++c_.slew_limited;
    }
    prev_[i] = f;
    out.force[i] = f;
  }
  out.flags = flags | (in.flags & ~(kFlagStale | kFlagClamped | kFlagFault));
}

namespace {

// v within +-limit, zero if not finite; counts what it changed.
float limited(float v, double limit, std::uint32_t& flags, GateCounters& c) noexcept {
  if (!std::isfinite(v)) {
    flags |= kTactileFault;
    ++c.tactile_non_finite;
    return 0.0f;
  }
  if (std::abs(v) > limit) {
    flags |= kTactileClamped;
    ++c.tactile_clamped;
    return static_cast<float>(std::copysign(limit, v));
  }
  return v;
}

}  // namespace

void SafetyGate::apply_tactile(const TactileCommand& in, TactileCommand& out) noexcept {
  ++c_.tactile_commands;
  std::uint32_t flags = gain_ < 1.0 ? kTactileFaded : 0u;
  const float g = static_cast<float>(gain_);
  for (int i = 0; i < kMaxFingers; ++i) {
    const TactileFrame& a = in.finger[i];
    TactileFrame& b = out.finger[i];
    const bool here = i < fingers_;
    b.samples = here && tactile_.vibration() ? std::clamp(a.samples, 0, kMaxTactileSamples) : 0;
    for (int k = 0; k < b.samples; ++k) b.vibration[k] = g * limited(a.vibration[k], tactile_.max_vibration, flags, c_);
    const bool pins = here && tactile_.pins() && a.rows == tactile_.pin_rows && a.cols == tactile_.pin_cols;
    b.rows = pins ? a.rows : 0;
    b.cols = pins ? a.cols : 0;
    for (int k = 0; k < b.rows * b.cols; ++k) b.pins[k] = g * limited(a.pins[k], tactile_.max_pin, flags, c_);
  }
  out.flags = flags;
}

}  // namespace hapticloth::devices
