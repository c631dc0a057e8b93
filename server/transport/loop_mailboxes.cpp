#include "transport/loop_mailboxes.hpp"

#include <algorithm>
#include <cmath>

namespace hapticloth::transport {

namespace {
void copy3(std::array<float, 3>& dst, const Eigen::Vector3d& v) {
  dst = {static_cast<float>(v.x()), static_cast<float>(v.y()), static_cast<float>(v.z())};
}

LoopMailboxes::ClothFrame sized_frame(std::size_t vertices) {
  LoopMailboxes::ClothFrame f;
  f.x.resize(vertices);
  return f;
}

TactileLayout layout_of(const devices::DeviceInfo& d) {
  const devices::TactileCapability& c = d.tactile;
  TactileLayout l;
  l.samples = c.vibration() ? static_cast<int>(std::lround(c.vibration_rate / d.nominal_rate)) : 0;
  l.rows = c.pin_rows;
  l.cols = c.pin_cols;
  l.sample_rate = c.vibration_rate;
  l.pin_pitch = static_cast<float>(c.pin_pitch);
  return l;
}
}  // namespace

LoopMailboxes::LoopMailboxes(std::size_t vertices, const devices::DeviceInfo& device, double cloth_rate,
                             double weft_period, double warp_period)
    : fingers_(device.fingers),
      cloth_period_(1.0 / cloth_rate),
      cloth_(sized_frame(vertices)),
      stats_(LoopSummary{}),
      samples_(kSamples),
      layout_(layout_of(device)),
      tactile_(device.tactile.any() ? kTactileSamples : 1) {
  layout_.weft_period = static_cast<float>(weft_period);
  layout_.warp_period = static_cast<float>(warp_period);
}

void LoopMailboxes::put_tactile(const haptics::HapticReport& r, const haptics::TactileRendering& t,
                                const devices::TactileCommand& out) noexcept {
  TactileSample s;
  s.time = r.time;
  s.tick = r.tick;
  s.out = out;
  for (int f = 0; f < fingers_; ++f) {
    const haptics::TactilePlace& p = t.place(f);
    s.u[f] = static_cast<float>(p.u);
    s.v[f] = static_cast<float>(p.v);
    s.normal_force[f] = static_cast<float>(p.normal_force);
    s.touching[f] = p.touching;
  }
  if (!tactile_.push(s)) tactile_dropped_.fetch_add(1, std::memory_order_relaxed);
}

void LoopMailboxes::take_tactile(std::vector<TactileSample>& out) {
  TactileSample s;
  while (out.size() < out.capacity() && tactile_.pop(s)) out.push_back(s);
}

void LoopMailboxes::put_refined(const haptics::RefinedRegions& r) noexcept {
  try {
    refined_.refined_x.resize(r.x.size());
    for (std::size_t i = 0; i < r.x.size(); ++i) copy3(refined_.refined_x[i], r.x[i]);
    refined_.refined_triangles.assign(r.triangles.begin(), r.triangles.end());
    refined_.refined_uv.resize(r.weave_uv.size());
    for (std::size_t t = 0; t < r.weave_uv.size(); ++t)
      for (int k = 0; k < 3; ++k)
        refined_.refined_uv[t][k] = {static_cast<float>(r.weave_uv[t][k][0]), static_cast<float>(r.weave_uv[t][k][1])};
    refined_.refined_region.assign(r.region.begin(), r.region.end());
  } catch (const std::bad_alloc&) {  // the frames then show no refinement rather than stop the step
    refined_.refined_x.clear();
    refined_.refined_triangles.clear();
    refined_.refined_uv.clear();
    refined_.refined_region.clear();
  }
}

void LoopMailboxes::put_cloth(const haptics::ClothSnapshot& s) noexcept {
  if (next_cloth_time_ >= 0.0 && s.time < next_cloth_time_ - 1e-9) return;
  next_cloth_time_ =
      std::max(next_cloth_time_ < 0.0 ? s.time : next_cloth_time_, s.time - cloth_period_) + cloth_period_;
  ClothFrame& f = cloth_.back();
  if (f.x.size() != s.x.size()) return;  // another mesh: never resize here
  f.time = s.time;
  f.step = s.step;
  for (std::size_t i = 0; i < s.x.size(); ++i) copy3(f.x[i], s.x[i]);
  try {
    f.refined_x = refined_.refined_x;  // vector copy-assignment keeps f's storage when it fits
    f.refined_triangles = refined_.refined_triangles;
    f.refined_uv = refined_.refined_uv;
    f.refined_region = refined_.refined_region;
  } catch (const std::bad_alloc&) {
    f.refined_x.clear();
    f.refined_triangles.clear();
    f.refined_uv.clear();
    f.refined_region.clear();
  }
  cloth_.publish();
}

void LoopMailboxes::put_tick(const haptics::HapticReport& r, const devices::DeviceState& state,
                             const devices::DeviceCommand& cmd) noexcept {
  const bool stale = (cmd.flags & devices::kFlagStale) != 0;
  if (stale && !was_stale_) watchdog_trips_.fetch_add(1, std::memory_order_relaxed);
  was_stale_ = stale;
  if (cmd.flags & devices::kFlagFault) nan_forces_.fetch_add(1, std::memory_order_relaxed);

  HapticSample s;
  s.time = r.time;
  s.tick = r.tick;
  s.flags = static_cast<std::int32_t>(cmd.flags);
  for (int f = 0; f < fingers_; ++f) {
    const haptics::FingerReport& fr = r.finger[f];
    copy3(s.device[f], state.finger[f].position);
    copy3(s.position[f], fr.position);
    copy3(s.proxy[f], fr.proxy);
    copy3(s.force[f], fr.force);
    copy3(s.command[f], cmd.force[f]);
    s.contact[f] = fr.in_contact;
    s.slipping[f] = fr.slipping;
  }
  if (!samples_.push(s)) dropped_.fetch_add(1, std::memory_order_relaxed);  // publisher behind
}

void LoopMailboxes::put_stats(const haptics::LoopStats& s) noexcept {
  stats_.back() = summarize(s);
  stats_.publish();
}

const LoopMailboxes::ClothFrame* LoopMailboxes::take_cloth() {
  return cloth_.acquire() ? &cloth_.front() : nullptr;
}

const LoopSummary* LoopMailboxes::take_stats() { return stats_.acquire() ? &stats_.front() : nullptr; }

void LoopMailboxes::take_samples(std::vector<HapticSample>& out) {
  HapticSample s;
  while (out.size() < out.capacity() && samples_.pop(s)) out.push_back(s);
}

}  // namespace hapticloth::transport
