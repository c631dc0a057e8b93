#include "haptics/sim_worker.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <Eigen/Geometry>

namespace hapticloth::haptics {

namespace {
// Direct coupling puts the fingertip proxies in the system, with contacts far stiffer than the
// cloth: backward Euler (alpha 1, L-stable) damps them; at alpha 0.5 they ring and the step
// blows up (hapticloth-bench stability). The server's stages say so when the scene asks for
// less.
cloth::IntegratorConfig with_proxies(cloth::IntegratorConfig c, int proxies) {
  c.proxies = proxies;
  if (proxies > 0) c.alpha = 1.0;
  return c;
}
// The scene's fingertip as the contact model sees it: field by field, as the transport codec
// maps the loop's figures into its message (alike in shape only: other fields).
ContactParams contact_params(const FingerParams& f, double margin) {
  ContactParams p;
  p.radius = f.radius;
  p.coupling_stiffness = f.stiffness;
  p.coupling_damping = f.damping;
  p.friction = f.friction;
  p.pressure_stiffness = f.contact_stiffness;
  p.max_force = f.max_force;
  p.margin = margin;
  return p;
}
double mean_edge(const cloth::ClothModel& m, const std::vector<std::array<int, 3>>& tris) {
  double edge = 0.0;
  int ne = 0;
  for (const auto& t : tris)
    for (int k = 0; k < 3; ++k, ++ne)
      edge += (m.rest_positions[t[k]] - m.rest_positions[t[(k + 1) % 3]]).norm();
  return ne ? edge / ne : 0.0;
}
}  // namespace

SimWorker::SimWorker(const cloth::ClothModel& model, const cloth::IntegratorConfig& cfg,
                     std::unique_ptr<cloth::LinearSolver> solver, const cloth::ClothState& start,
                     int fingers, const FingerParams& finger, const CouplingParams& coupling,
                     Rendering mode, TripleBuffer<ClothSnapshot>& to_haptics,
                     TripleBuffer<HapticReport>& from_haptics)
    : model_(model),
      integ_(model, with_proxies(cfg, mode == Rendering::Patch ? 0 : fingers), std::move(solver)),
      s_(start),
      fingers_(fingers),
      fp_(finger),
      cp_(coupling),
      out_(to_haptics),
      in_(from_haptics),
      tris_(model.triangles) {
  kernel_r_ = cp_.kernel_radius > 0.0 ? cp_.kernel_radius
                                      : std::max(fp_.radius, 2.0 * mean_edge(model_, tris_));
  response_on_ = mode == Rendering::Response;
  if (mode == Rendering::Patch) {
    kernel_ = std::make_unique<KernelCoupling>(model_, tris_, fingers_, kernel_r_, cp_.finger_mass);
  } else {
    tips_ = std::make_unique<FingertipContact>(model_, tris_, fingers_,
                                               contact_params(fp_, cp_.margin), integ_);
    if (refines(cp_.refine, mode == Rendering::Response) &&
        mesh_needs_refinement(model_, cp_.refinement, fp_.radius))
      refine_ = std::make_unique<LocalRefinement>(model_, contact_params(fp_, cp_.margin),
                                                  integ_.config().gravity, cp_.refinement);
  }
  mine_.resize(model_.num_vertices(), static_cast<int>(to_haptics.back().near_triangles[0].size()));
}

// The device's fingertips at the end of the coming step: the latest tick's positions carried
// forward at their velocity (the coupling then acts at the end of the step, implicitly).
std::array<FingerTarget, kMaxFingers> SimWorker::fingertip_targets(const HapticReport& r,
                                                                   double now) const {
  std::array<FingerTarget, kMaxFingers> t{};
  const double h = integ_.config().dt;
  const double ahead = std::clamp(now + h - r.time, 0.0, 2.0 * h);
  for (int f = 0; f < fingers_ && r.time >= 0.0; ++f) {
    t[f].valid = r.finger[f].present;
    t[f].position = r.finger[f].position + ahead * r.finger[f].velocity;
    t[f].velocity = r.finger[f].velocity;
  }
  return t;
}

// Which fingertips are within reach of the cloth's bounding box (the local patches skip the
// others).
void SimWorker::mark_near(const HapticReport& r) {
  ClothSnapshot& snap = out_.back();
  Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
  for (const auto& x : s_.x) {
    lo = lo.cwiseMin(x);
    hi = hi.cwiseMax(x);
  }
  const double reach = fp_.radius + cp_.margin;
  for (int fi = 0; fi < fingers_; ++fi) {
    const Vec3& p = r.finger[fi].position;
    snap.near[fi] = r.time >= 0.0 && r.finger[fi].present && (p.array() >= lo.array() - reach).all() &&
                    (p.array() <= hi.array() + reach).all();
  }
  if (patch_radius_ > 0.0) mark_patch_candidates(r, snap);
}

// The patch model's candidates per finger: the global triangles with a corner within the patch
// radius of anywhere the fingertip can be before the next snapshot (its travel at its present
// speed over two steps, plus the contact margin), in index order, up to the snapshot's room
// (the rest counted). One pass over the triangles here, on the simulation thread, so the
// haptic thread's patch builds cost what the patch holds, not what the mesh holds.
void SimWorker::mark_patch_candidates(const HapticReport& r, ClothSnapshot& snap) {
  const double dt = integ_.config().dt;
  for (int f = 0; f < fingers_; ++f) {
    std::vector<int>& out = snap.near_triangles[f];
    const int room = static_cast<int>(out.size());
    int n = 0;
    if (snap.near[f]) {
      const Vec3& c = r.finger[f].position;
      const double reach = patch_radius_ + 2.0 * dt * r.finger[f].velocity.norm() + cp_.margin;
      const double reach2 = reach * reach;
      bool overflow = false;
      for (int t = 0; t < static_cast<int>(tris_.size()); ++t) {
        const auto& g = tris_[t];
        bool in = false;
        for (int k = 0; k < 3; ++k) in = in || (s_.x[g[k]] - c).squaredNorm() < reach2;
        if (!in) continue;
        if (n < room) out[n++] = t;
        else overflow = true;
      }
      patch_overflows_ += overflow;
    }
    snap.near_count[f] = n;
  }
}

Vec3 SimWorker::applied_force() const {
  if (kernel_) return kernel_->applied_force();
  Vec3 F = Vec3::Zero();
  for (int f = 0; f < fingers_; ++f) F -= tips_->result(f).force;
  return F;
}

void SimWorker::publish(double now) {
  in_.acquire();
  const HapticReport& r = in_.front();
  mark_near(r);
  ClothSnapshot& snap = out_.back();
  snap.time = now;
  snap.step = steps_;
  std::copy(s_.x.begin(), s_.x.end(), snap.x.begin());
  std::copy(s_.v.begin(), s_.v.end(), snap.v.begin());
  for (int f = 0; f < fingers_; ++f) snap.proxy[f] = tips_ ? tips_->result(f) : ProxyResult{};
  mine_.assign(snap);
  out_.publish();
}

// The multirate path's local model: the step's response to the fingertips (eq. 9 linearized),
// for the haptic loop to render from until the next step.
void SimWorker::hand_over_response() {
  ClothSnapshot& snap = out_.back();
  snap.has_response = integ_.proxy_response(response_);
  for (int p = 0; p < fingers_; ++p)
    for (int q = 0; q < fingers_; ++q)
      snap.response[p * kMaxFingers + q] = snap.has_response ? response_[p * fingers_ + q] : cloth::Mat3::Zero();
}

void SimWorker::step(double now) {
  const auto t0 = std::chrono::steady_clock::now();
  in_.acquire();
  const HapticReport& r = in_.front();
  {
    const auto awake = integ_.keep_helper_awake();  // it wakes during the contact search
    if (tips_)
      tips_->begin_step(s_, fingertip_targets(r, now), integ_.config().dt);
    else
      kernel_->apply(r, s_, integ_);
    integ_.step(s_);
  }
  if (tips_) tips_->end_step(s_);
  if (refine_) refine_->update(s_, *tips_, fingers_);
  if (response_on_) hand_over_response();
  ++steps_;
  publish(now);
  last_step_us_ = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count();
  step_us_.add(last_step_us_);
  helper_wait_us_.add(1e3 * integ_.last_timing().helper_wait_ms);
}

}  // namespace hapticloth::haptics
