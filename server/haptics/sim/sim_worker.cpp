#include "haptics/sim/sim_worker.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "haptics/modes/rendering_modes.hpp"

namespace hapticloth::haptics {

SimWorker::SimWorker(const cloth::ClothModel& model, const cloth::IntegratorConfig& cfg,
                     std::unique_ptr<cloth::LinearSolver> solver, const cloth::ClothState& start,
                     int fingers, const FingerParams& finger, const CouplingParams& coupling,
                     Rendering mode, const PatchParams& patch, TripleBuffer<ClothSnapshot>& to_haptics,
                     TripleBuffer<HapticReport>& from_haptics)
    : integ_(model, integrator_config(mode, cfg, fingers), std::move(solver)),
      s_(start),
      fingers_(fingers),
      reach_(finger.radius + coupling.margin),
      out_(to_haptics),
      in_(from_haptics),
      coupling_(make_sim_coupling(mode, model, integ_, fingers, finger, coupling, patch)) {
  last_snapshot_.resize(model.num_vertices(), static_cast<int>(to_haptics.back().near_triangles[0].size()));
}

// Which fingertips are within reach of the cloth's bounding box (the haptic loop's contact
// skips the others).
void SimWorker::mark_near(const HapticReport& r, ClothSnapshot& snap) const {
  Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
  for (const auto& x : s_.x) {
    lo = lo.cwiseMin(x);
    hi = hi.cwiseMax(x);
  }
  for (int fi = 0; fi < fingers_; ++fi) {
    const Vec3& p = r.finger[fi].position;
    snap.near[fi] = r.time >= 0.0 && r.finger[fi].present && (p.array() >= lo.array() - reach_).all() &&
                    (p.array() <= hi.array() + reach_).all();
  }
}

void SimWorker::publish(double now) {
  in_.acquire();
  const HapticReport& r = in_.front();
  ClothSnapshot& snap = out_.back();
  mark_near(r, snap);
  snap.time = now;
  snap.step = steps_;
  std::copy(s_.x.begin(), s_.x.end(), snap.x.begin());
  std::copy(s_.v.begin(), s_.v.end(), snap.v.begin());
  coupling_->fill(r, s_, snap);
  last_snapshot_.assign(snap);
  out_.publish();
}

void SimWorker::step(double now) {
  const auto t0 = std::chrono::steady_clock::now();
  in_.acquire();
  {
    const auto awake = integ_.keep_helper_awake();  // it wakes during the contact search
    coupling_->couple(in_.front(), now, s_);
    integ_.step(s_);
  }
  coupling_->conclude(s_);
  ++steps_;
  publish(now);
  last_step_us_ = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count();
  step_us_.add(last_step_us_);
  helper_wait_us_.add(1e3 * integ_.last_timing().helper_wait_ms);
}

}  // namespace hapticloth::haptics
