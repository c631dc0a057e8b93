#include "haptics/loop/haptic_loop.hpp"

#include <algorithm>
#include <cmath>


namespace hapticloth::haptics {

HapticLoop::HapticLoop(devices::DeviceHandle& device, devices::SafetyGate& gate,
                       const FingerParams& finger, const DeviceMapping& map,
                       std::unique_ptr<SurfaceContact> contact, Rendering mode,
                       TripleBuffer<ClothSnapshot>& from_sim, TripleBuffer<HapticReport>& to_sim)
    : dev_(device),
      gate_(gate),
      fp_(finger),
      k_(std::min(finger.stiffness, device.info().max_stiffness)),
      map_(map),
      in_(from_sim),
      out_(to_sim),
      fingers_(device.info().fingers),
      period_(1.0 / device.info().nominal_rate),
      contact_(std::move(contact)),
      catch_up_(period_),
      passivity_(k_, gate.max_force()) {
  sent_.fill(Vec3::Zero());
  damp_.fill(Vec3::Zero());
  // The multirate path renders from a model that is not the cloth itself: bounded by energy.
  if (multirate(mode)) bound_ = std::make_unique<EnergyBound>(period_);
}

bool HapticLoop::wind_down(double now) noexcept {
  if (dev_.read(now, state_) == devices::Status::Error) ++device_errors_;
  cmd_ = devices::DeviceCommand{};
  gate_.apply(now, state_.received_time, cmd_, gated_);
  if (dev_.write(now, gated_) == devices::Status::Error) ++device_errors_;
  if (tactile_) {  // the display falls silent with the forces
    tactile_cmd_ = devices::TactileCommand{};
    gate_.apply_tactile(tactile_cmd_, tactile_gated_);
    if (dev_.write_tactile(now, tactile_gated_) == devices::Status::Error) ++device_errors_;
  }
  last_now_ = now;
  // The report of the tick, for the session's observers (the LCM log, the MCAP): the force
  // each finger is sent, fading to zero through the gate; the contact as the last tick left it.
  ++tick_;
  report_.time = now;
  report_.tick = tick_;
  for (int f = 0; f < fingers_; ++f) report_.finger[f].force = map_.R * gated_.force[f];
  for (int f = 0; f < fingers_; ++f)
    if (!gated_.force[f].isZero(0.0)) return false;
  return true;
}

void HapticLoop::prime(double now) noexcept {
  if (dev_.read(now, state_) == devices::Status::Error) ++device_errors_;
  const Presence present = presence(now);
  report_.time = now;
  report_.tick = 0;
  for (int f = 0; f < fingers_; ++f) {
    FingerReport& r = report_.finger[f];
    absent(r, map_.origin + map_.R * state_.finger[f].position, map_.R * state_.finger[f].velocity);
    r.present = present[f];
  }
  out_.back() = report_;
  out_.publish();
}

// An absent finger's report: where the device says it is, touching nothing, no force.
void HapticLoop::absent(FingerReport& r, const Vec3& centre, const Vec3& velocity) noexcept {
  const std::uint64_t impacts = r.impacts;
  r = FingerReport{};
  r.position = centre;
  r.proxy = centre;
  r.velocity = velocity;
  r.impacts = impacts;
}

// The multirate models' forces within what the hand has put into them (energy_bound.hpp); what
// is scaled back is taken from the model's force, so the cloth gets the reaction of what the
// hand gets, and the proxy stays where the coupling spring puts it.
void HapticLoop::bound_energy(const std::array<Fingertip, kMaxFingers>& tips) noexcept {
  std::array<Vec3, kMaxFingers> force{}, v{};
  std::array<bool, kMaxFingers> touching{};
  for (int f = 0; f < fingers_; ++f) {
    force[f] = report_.finger[f].force;
    v[f] = tips[f].velocity;
    touching[f] = report_.finger[f].in_contact;
  }
  bound_->limit(force, v, touching, fingers_);
  for (int f = 0; f < fingers_; ++f) {
    FingerReport& r = report_.finger[f];
    const Vec3 cut = force[f] - r.force;
    r.force += cut;
    r.spring += cut;
    r.proxy += cut / k_;
  }
}

void HapticLoop::tick(double now) noexcept {
  ++tick_;
  const double tick_dt = last_now_ >= 0.0 ? std::clamp(now - last_now_, 0.0, 0.05) : 0.0;
  if (dev_.read(now, state_) == devices::Status::Error) ++device_errors_;
  in_.acquire();
  const ClothSnapshot& s = in_.front();
  count_out_of_reach(s);
  report_.time = now;
  report_.tick = tick_;
  const Presence present = presence(now);
  std::array<Fingertip, kMaxFingers> tips{};
  std::array<Vec3, kMaxFingers> measured{};
  read_fingertips(tick_dt, present, tips, measured);
  touch(s, now, tick_dt, present, tips, measured);
  if (bound_) bound_energy(tips);
  command(tick_dt, present, tips, measured);
  gate_.apply(now, state_.received_time, cmd_, gated_);
  if (dev_.write(now, gated_) == devices::Status::Error) ++device_errors_;
  for (int f = 0; f < fingers_; ++f) sent_[f] = map_.R * gated_.force[f];
  report_felt_forces();
  if (tactile_) render_tactile(s, now, tick_dt);
  out_.back() = report_;
  out_.publish();
  last_now_ = now;
}

// A finger is there only while the device has a fresh sample of it: before its first sample
// the device's position means nothing (a UDP rig not yet connected reads as the device origin,
// which may be inside the cloth), and after a watchdog trip it is unknown. A composite device
// says so per finger (DeviceState::absent).
HapticLoop::Presence HapticLoop::presence(double now) const noexcept {
  const bool fresh = gate_.fresh(now, state_.received_time);
  Presence p{};
  for (int f = 0; f < fingers_; ++f) p[f] = fresh && !((state_.absent >> f) & 1u);
  return p;
}

void HapticLoop::count_out_of_reach(const ClothSnapshot& s) noexcept {
  bool any_near = false;
  for (int f = 0; f < fingers_; ++f) any_near = any_near || (s.time >= 0.0 && s.near[f]);
  if (!any_near) ++out_of_reach_;
}

// The device's fingertips in the scene frame (`measured`), and as the contact takes them
// (`tips`): a late tick's motion reaches the contact over the ticks it missed (late_tick.hpp).
void HapticLoop::read_fingertips(double tick_dt, const Presence& present, std::array<Fingertip, kMaxFingers>& tips,
                                 std::array<Vec3, kMaxFingers>& measured) noexcept {
  if (catch_up_.late(tick_dt)) ++late_ticks_;
  for (int f = 0; f < fingers_; ++f) {
    measured[f] = map_.origin + map_.R * state_.finger[f].position;
    const bool catch_up = present[f] && guard_;
    tips[f] = Fingertip{f, catch_up ? catch_up_.seen(f, measured[f], tick_dt) : measured[f],
                        map_.R * state_.finger[f].velocity};
  }
}

// Each finger's contact with the cloth (the mode's haptic half), or its absence; the energy
// bound takes the interval that ended first (it needs the force held over it).
void HapticLoop::touch(const ClothSnapshot& s, double now, double tick_dt, const Presence& present,
                       const std::array<Fingertip, kMaxFingers>& tips,
                       const std::array<Vec3, kMaxFingers>& measured) noexcept {
  contact_->prepare(s, tips, present, fingers_);
  if (bound_) bound_->account(measured, sent_, present, fingers_);
  bool contact = false;
  for (int f = 0; f < fingers_; ++f) {
    FingerReport& r = report_.finger[f];
    if (present[f]) {
      contact_->touch(s, now, tick_dt, tips[f], r);
    } else {
      if (r.present) contact_->release(f);
      absent(r, tips[f].centre, tips[f].velocity);
      catch_up_.reset(f);
      passivity_.reset(f);
    }
    r.present = present[f];
    contact = contact || r.in_contact;
  }
  if (contact) ++contact_ticks_;
}

// The command per finger in the device frame: the contact's force, plus the passivity
// controller's damping where the coupling gave energy over the last interval.
void HapticLoop::command(double tick_dt, const Presence& present, const std::array<Fingertip, kMaxFingers>& tips,
                         const std::array<Vec3, kMaxFingers>& measured) noexcept {
  for (int f = 0; f < fingers_; ++f) {
    const FingerReport& r = report_.finger[f];
    Vec3& damp = damp_[f];
    damp.setZero();
    if (present[f])
      damp = passivity_.observe(f, tick_dt, sent_[f], measured[f], r.proxy, tips[f].velocity, r.force,
                                r.spring, r.in_contact);
    if (!guard_) damp.setZero();
    cmd_.force[f] = map_.R.transpose() * (r.force + damp);
  }
}

// The simulation gets what the user actually feels (after the gate), in the scene frame, but
// for the passivity controller's damping, which acts between the hand and the coupling only:
// the contact's force, scaled as the gate scaled the command (clamp, fade). (Subtracting the
// damping from the gated force instead lets a clamped command hand the cloth more than the
// contact asked, energy the cloth never gave, enough to make a long global step blow up.)
void HapticLoop::report_felt_forces() noexcept {
  for (int f = 0; f < fingers_; ++f) {
    FingerReport& r = report_.finger[f];
    if (!r.in_contact) continue;
    if (damp_[f].isZero(0.0)) {
      r.force = map_.R * gated_.force[f];
    } else {
      const double asked = (r.force + damp_[f]).norm();
      r.force *= asked > 0.0 ? std::min(1.0, gated_.force[f].norm() / asked) : 0.0;
    }
  }
}

// What the skin feels this tick, through the same gate as the forces (its fade, the display's
// limits), after the force is written: the force's latency comes first.
void HapticLoop::render_tactile(const ClothSnapshot& s, double now, double tick_dt) noexcept {
  tactile_->render(s, report_, now, tick_dt, tactile_cmd_);
  gate_.apply_tactile(tactile_cmd_, tactile_gated_);
  if (dev_.write_tactile(now, tactile_gated_) == devices::Status::Error) ++device_errors_;
}

}  // namespace hapticloth::haptics
