#include "transport/hub_publisher.hpp"

#include <algorithm>
#include <chrono>

namespace hapticloth::transport {

namespace {
constexpr int kMaxSamplesPerMessage = 100;
}  // namespace

HubPublisher::HubPublisher(const TransportOptions& opt, SceneMessages& scene, LoopMailboxes& loops,
                           HubEvents& events, const CommandIntake& commands, HubTransports& out)
    : scene_(scene), loops_(loops), events_(events), commands_(commands), out_(out) {
  batch_.reserve(LoopMailboxes::kSamples);
  if (loops_.has_tactile()) tactile_batch_.reserve(LoopMailboxes::kTactileSamples);
  const double period = std::clamp(std::min(opt.haptic_batch, 1.0 / opt.cloth_rate), 1e-3, 0.1);
  thread_ = std::thread([this, period] { run(period); });
}

HubPublisher::~HubPublisher() { stop(); }

void HubPublisher::stop() {
  {
    std::lock_guard<std::mutex> lock(run_mu_);
    stop_ = true;
  }
  wake_.notify_one();
  if (thread_.joinable()) thread_.join();
}

void HubPublisher::flush() {
  std::unique_lock<std::mutex> lock(run_mu_);
  const std::uint64_t want = ++flush_request_;
  wake_.notify_one();
  flushed_.wait_for(lock, std::chrono::seconds(5), [&] { return flush_done_ >= want || stop_; });
}

// Every period, or at once for a flush; a flush waits for the pass that started after it.
void HubPublisher::run(double period) {
  const auto tick = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(period));
  auto next = std::chrono::steady_clock::now() + tick;
  for (;;) {
    std::uint64_t req;
    {
      std::unique_lock<std::mutex> lock(run_mu_);
      wake_.wait_until(lock, next, [&] { return stop_ || flush_request_ != flush_done_; });
      if (stop_) break;
      req = flush_request_;
    }
    const auto now = std::chrono::steady_clock::now();
    if (now >= next) next = std::max(next + tick, now);
    publish_pending();
    {
      std::lock_guard<std::mutex> lock(run_mu_);
      flush_done_ = req;
    }
    flushed_.notify_all();
  }
  publish_pending();  // the last samples, statistics and events
  flushed_.notify_all();
}

void HubPublisher::publish_pending() {
  if (scene_.take_request()) publish_scene();
  publish_cloth();
  publish_haptics();
  publish_tactile();
  publish_stats();
  // Faults the haptic loop counted: one event per new batch of them.
  events_.post_faults(loops_.watchdog_trips(), loops_.nan_forces());
  publish_events();
}

template <class M>
void HubPublisher::send_msg(Topic t, const M& m) {
  encode(m, buf_);
  out_.send(t, buf_);
}

void HubPublisher::publish_scene() {
  if (out_.admit(Topic::Scene)) out_.send(Topic::Scene, scene_.info_bytes());
  if (out_.admit(Topic::Topology)) {
    hapticloth::cloth_topology_t m;
    scene_.topology(m);
    send_msg(Topic::Topology, m);
  }
}

// The refined children under the fingertips (cloth_state_t's refined fields).
void HubPublisher::fill_refined(const LoopMailboxes::ClothFrame& f) {
  hapticloth::cloth_state_t& m = cloth_msg_;
  m.num_refined_vertices = static_cast<int32_t>(f.refined_x.size());
  m.num_refined_triangles = static_cast<int32_t>(f.refined_triangles.size());
  m.num_refined_region = static_cast<int32_t>(f.refined_region.size());
  m.refined_positions.resize(f.refined_x.size());
  for (std::size_t i = 0; i < f.refined_x.size(); ++i)
    m.refined_positions[i].assign(f.refined_x[i].begin(), f.refined_x[i].end());
  m.refined_triangles.resize(f.refined_triangles.size());
  m.refined_weave_uv.resize(f.refined_triangles.size());
  for (std::size_t t = 0; t < f.refined_triangles.size(); ++t) {
    m.refined_triangles[t].assign(f.refined_triangles[t].begin(), f.refined_triangles[t].end());
    m.refined_weave_uv[t].resize(3);
    for (int k = 0; k < 3; ++k) m.refined_weave_uv[t][k].assign(f.refined_uv[t][k].begin(), f.refined_uv[t][k].end());
  }
  m.refined_region.assign(f.refined_region.begin(), f.refined_region.end());
}

void HubPublisher::publish_cloth() {
  const LoopMailboxes::ClothFrame* f = loops_.take_cloth();
  if (!f || !out_.admit(Topic::Cloth)) return;
  cloth_msg_.utime = wall_utime();
  cloth_msg_.time = f->time;
  cloth_msg_.step = static_cast<int64_t>(f->step);
  cloth_msg_.num_vertices = static_cast<int32_t>(f->x.size());
  cloth_msg_.positions.resize(f->x.size());
  for (std::size_t i = 0; i < f->x.size(); ++i) cloth_msg_.positions[i].assign(f->x[i].begin(), f->x[i].end());
  fill_refined(*f);
  send_msg(Topic::Cloth, cloth_msg_);
}

void HubPublisher::publish_haptics() {
  batch_.clear();
  loops_.take_samples(batch_);
  for (std::size_t k = 0; k < batch_.size(); k += kMaxSamplesPerMessage) {
    if (!out_.admit(Topic::Haptics)) continue;
    const int n = static_cast<int>(std::min<std::size_t>(kMaxSamplesPerMessage, batch_.size() - k));
    fill(batch_.data() + k, n, loops_.fingers(), haptic_msg_);
    send_msg(Topic::Haptics, haptic_msg_);
  }
}

void HubPublisher::publish_tactile() {
  if (!loops_.has_tactile()) return;
  tactile_batch_.clear();
  loops_.take_tactile(tactile_batch_);
  for (std::size_t k = 0; k < tactile_batch_.size(); k += kMaxSamplesPerMessage) {
    if (!out_.admit(Topic::Tactile)) continue;
    const int n = static_cast<int>(std::min<std::size_t>(kMaxSamplesPerMessage, tactile_batch_.size() - k));
    fill(tactile_batch_.data() + k, n, loops_.fingers(), loops_.tactile_layout(), tactile_msg_);
    send_msg(Topic::Tactile, tactile_msg_);
  }
}

void HubPublisher::publish_stats() {
  const LoopSummary* s = loops_.take_stats();
  if (!s || !out_.admit(Topic::Stats)) return;
  hapticloth::loop_stats_t m;
  fill(*s, m);
  send_msg(Topic::Stats, m);
}

// The events posted since the last pass, each with the fault counters as they are now; the
// commands received, to the log.
void HubPublisher::publish_events() {
  if (!events_.take(events_out_, commands_out_)) return;
  for (const auto& c : commands_out_) out_.log_command(c);
  for (const auto& e : events_out_) {
    if (!out_.admit(Topic::Events)) continue;
    hapticloth::event_t m;
    m.utime = e.utime;
    m.kind = e.kind;
    m.text = e.text;
    m.watchdog_trips = static_cast<int64_t>(loops_.watchdog_trips());
    m.nan_forces = static_cast<int64_t>(loops_.nan_forces());
    m.dropped_packets = static_cast<int64_t>(events_.dropped_packets());
    m.rejected_commands = static_cast<int64_t>(commands_.rejected());
    send_msg(Topic::Events, m);
  }
  events_out_.clear();
  commands_out_.clear();
}

}  // namespace hapticloth::transport
