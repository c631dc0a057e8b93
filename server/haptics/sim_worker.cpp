#include "haptics/sim_worker.hpp"

#include <algorithm>
#include <chrono>

#include <Eigen/Geometry>
#include <cmath>

namespace hapticloth::haptics {

namespace {
std::vector<std::array<int, 3>> triangles_of(const cloth::ClothModel& m) {
  std::vector<std::array<int, 3>> t;
  t.reserve(m.elements.size());
  for (const auto& e : m.elements) t.push_back({e.v[0], e.v[1], e.v[2]});
  return t;
}
}  // namespace

SimWorker::SimWorker(const cloth::ClothModel& model, const cloth::IntegratorConfig& cfg,
                     std::unique_ptr<cloth::LinearSolver> solver, const cloth::ClothState& start,
                     int fingers, const FingerParams& finger, const CouplingParams& coupling,
                     TripleBuffer<ClothSnapshot>& to_haptics,
                     TripleBuffer<HapticReport>& from_haptics)
    : model_(model),
      integ_(model, cfg, std::move(solver)),
      s_(start),
      fingers_(fingers),
      fp_(finger),
      cp_(coupling),
      bp_(start.x, triangles_of(model)),
      out_(to_haptics),
      in_(from_haptics),
      tris_(triangles_of(model)) {
  double edge = 0.0;
  int ne = 0;
  for (const auto& t : tris_)
    for (int k = 0; k < 3; ++k, ++ne)
      edge += (model_.rest_positions[t[k]] - model_.rest_positions[t[(k + 1) % 3]]).norm();
  edge = ne ? edge / ne : 0.0;
  kernel_r_ = cp_.kernel_radius > 0.0 ? cp_.kernel_radius : std::max(fp_.radius, 2.0 * edge);
  normals_.assign(model_.num_vertices(), Vec3::UnitZ());
  w_.assign(model_.num_vertices(), 0.0);
  mine_.resize(model_.num_vertices());
  x_refit_ = start.x;
}

void SimWorker::vertex_normals() {
  std::fill(normals_.begin(), normals_.end(), Vec3::Zero());
  for (const auto& t : tris_) {
    const Vec3 n = (s_.x[t[1]] - s_.x[t[0]]).cross(s_.x[t[2]] - s_.x[t[0]]);  // area-weighted
    for (int k = 0; k < 3; ++k) normals_[t[k]] += n;
  }
  for (auto& n : normals_) {
    const double l = n.norm();
    n = l > 0.0 ? Vec3(n / l) : Vec3::UnitZ();
  }
}

double SimWorker::apply_impact(const FingerReport& c, double me) {
  const double R = kernel_r_, R2 = R * R;
  const Vec3& n = c.normal;
  double ms = 0.0, ps = 0.0;
  for (int i = 0; i < model_.num_vertices(); ++i) {
    w_[i] = 0.0;
    if (model_.pinned[i]) continue;
    const double d2 = (s_.x[i] - c.contact).squaredNorm();
    if (d2 >= R2) continue;
    const double u = 1.0 - d2 / R2;
    w_[i] = u * u;  // phi_i, 1 at the contact point
    ms += model_.mass[i] * w_[i];
    ps += model_.mass[i] * w_[i] * s_.v[i].dot(n);
  }
  if (ms <= 0.0 || me <= 0.0) return 0.0;
  const double vs = ps / ms, ve = c.velocity.dot(n);
  const double ves = (me * ve + ms * vs) / (me + ms);
  for (int i = 0; i < model_.num_vertices(); ++i)
    if (w_[i] > 0.0) s_.v[i] += w_[i] * (ves - vs) * n;
  return ms * (ves - vs);
}

void SimWorker::apply_contacts() {
  in_.acquire();
  const HapticReport& r = in_.front();
  for (int fi = 0; fi < fingers_; ++fi) {
    const FingerReport& c = r.finger[fi];
    if (r.time < 0.0 || !c.in_contact || c.impacts == impacts_seen_[fi]) continue;
    impacts_seen_[fi] = c.impacts;
    apply_impact(c, cp_.finger_mass);
  }
  auto& f = integ_.external_forces();
  auto& K = integ_.external_stiffness();
  bool any = false;
  applied_.setZero();
  for (int fi = 0; fi < fingers_; ++fi) any = any || (r.time >= 0.0 && r.finger[fi].in_contact);
  if (!any && !integ_.external_stiffness_on) return;
  std::fill(f.begin(), f.end(), Vec3::Zero());
  std::fill(K.begin(), K.end(), cloth::Mat3::Zero());
  integ_.external_stiffness_on = any;
  if (!any) return;
  const double R = kernel_r_, R2 = R * R;
  for (int fi = 0; fi < fingers_; ++fi) {
    const FingerReport& c = r.finger[fi];
    if (!c.in_contact) continue;
    // Kernel weights around the contact point (4.3): w ~ A_i (1 - d^2/R^2)^2, normalized.
    double sum = 0.0;
    for (int i = 0; i < model_.num_vertices(); ++i) {
      const double d2 = (s_.x[i] - c.contact).squaredNorm();
      w_[i] = 0.0;
      if (d2 >= R2 || model_.pinned[i]) continue;
      const double u = 1.0 - d2 / R2;
      w_[i] = model_.vertex_area[i] * u * u;
      sum += w_[i];
    }
    const Vec3 F = -c.force;  // the cloth gets the reaction of what the user feels
    applied_ += F;
    // Contact stiffness seen by the cloth: the normal spring, and while the friction sticks the
    // tangential spring too (the anchor holds the cloth in every direction). Entering the
    // implicit solve, it keeps the light vertices under the finger stable.
    const cloth::Mat3 nn = c.slipping ? cloth::Mat3(c.stiffness * c.normal * c.normal.transpose())
                                      : cloth::Mat3(c.stiffness * cloth::Mat3::Identity());
    if (sum <= 0.0) {  // kernel found no free vertex: the contact triangle's own corners
      const auto& t = tris_[c.triangle];
      for (int k = 0; k < 3; ++k) {
        f[t[k]] += c.bary[k] * F;
        K[t[k]] += c.bary[k] * nn;
      }
      continue;
    }
    for (int i = 0; i < model_.num_vertices(); ++i) {
      if (w_[i] == 0.0) continue;
      const double wi = w_[i] / sum;
      f[i] += wi * F;
      K[i] += wi * nn;  // row-sum lumped contact stiffness: the spring acts implicitly
    }
  }
}

void SimWorker::find_candidates() {
  ClothSnapshot& snap = out_.back();
  in_.acquire();
  const HapticReport& r = in_.front();
  // Skip the broad phase when no fingertip is near the cloth's bounding box.
  Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
  for (const auto& x : s_.x) {
    lo = lo.cwiseMin(x);
    hi = hi.cwiseMax(x);
  }
  const double reach = fp_.radius + cp_.margin;
  bool near = false;
  for (int fi = 0; fi < fingers_ && r.time >= 0.0; ++fi) {
    const Vec3& p = r.finger[fi].position;
    near = near || ((p.array() >= lo.array() - reach).all() && (p.array() <= hi.array() + reach).all());
  }
  if (!near) {
    for (int fi = 0; fi < fingers_; ++fi) {
      snap.ncand[fi] = 0;
      snap.overflow[fi] = false;
    }
    return;
  }
  // Refit lazily: the hierarchy stays conservative if the query grows by the largest vertex
  // displacement since the last refit; refit once that exceeds the slack.
  double disp2 = 0.0;
  for (size_t i = 0; i < s_.x.size(); ++i) disp2 = std::max(disp2, (s_.x[i] - x_refit_[i]).squaredNorm());
  double disp = std::sqrt(disp2);
  if (disp > cp_.refit_slack) {
    bp_.refit(s_.x);
    x_refit_ = s_.x;
    disp = 0.0;
    ++refits_;
  }
  for (int fi = 0; fi < fingers_; ++fi) {
    snap.ncand[fi] = 0;
    snap.overflow[fi] = false;
    if (r.time < 0.0) continue;
    const int n = bp_.query_sphere(r.finger[fi].position, fp_.radius + cp_.margin + disp,
                                   snap.cand[fi].data(), kMaxCandidates);
    snap.ncand[fi] = n;
    snap.overflow[fi] = n >= kMaxCandidates;
  }
}

void SimWorker::publish(double now) {
  vertex_normals();
  find_candidates();
  ClothSnapshot& snap = out_.back();
  snap.time = now;
  snap.step = steps_;
  std::copy(s_.x.begin(), s_.x.end(), snap.x.begin());
  std::copy(s_.v.begin(), s_.v.end(), snap.v.begin());
  std::copy(normals_.begin(), normals_.end(), snap.n.begin());
  mine_.assign(snap);
  out_.publish();
}

void SimWorker::step(double now) {
  const auto t0 = std::chrono::steady_clock::now();
  apply_contacts();
  integ_.step(s_);
  ++steps_;
  publish(now);
  step_us_.add(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
}

}  // namespace hapticloth::haptics
