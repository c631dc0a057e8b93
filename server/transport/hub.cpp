#include "transport/hub.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "transport/lcm_bus.hpp"
#include "transport/zenoh_session.hpp"

namespace hapticloth::transport {

namespace {
constexpr int kMaxSamplesPerMessage = 100;
constexpr const char* kTopicNames[kTopics] = {"topology", "cloth", "haptics", "stats", "events", "scene"};

void copy3(std::array<float, 3>& dst, const Eigen::Vector3d& v) {
  dst = {static_cast<float>(v.x()), static_cast<float>(v.y()), static_cast<float>(v.z())};
}
}  // namespace

const char* topic_name(Topic t) { return kTopicNames[static_cast<int>(t)]; }

std::string key_expression(const std::string& server, const std::string& topic) {
  return "hapticloth/" + server + "/" + topic;
}

std::string lcm_channel(const std::string& topic) {
  std::string c = "HAPTICLOTH_" + topic;
  std::transform(c.begin(), c.end(), c.begin(), [](unsigned char ch) { return std::toupper(ch); });
  return c;
}

Hub::Hub(const TransportOptions& opt, SceneInfo scene)
    : opt_(opt),
      scene_(std::move(scene)),
      fingers_(std::clamp(scene_.device.fingers, 1, devices::kMaxFingers)),
      max_speed_(opt.max_command_speed),
      cloth_([&] {
        ClothFrame f;
        f.x.resize(scene_.rest_positions.size());
        return f;
      }()),
      loop_(LoopSummary{}),
      ring_(kRing) {
  if (opt_.server_name.empty() || opt_.server_name.find_first_of("/*$?#") != std::string::npos)
    throw std::runtime_error("transport: server name '" + opt_.server_name +
                             "' must be non-empty without / * $ ? #");
  if (!(opt_.cloth_rate > 0.0) || !(opt_.haptic_batch > 0.0))
    throw std::runtime_error("transport: cloth rate and haptic batch must be positive");
  for (int t = 0; t < kTopics; ++t) channel_[t] = lcm_channel(kTopicNames[t]);
  batch_.reserve(kRing);

  // The scene answer, encoded once.
  hapticloth::scene_info_t si;
  si.utime = wall_utime();
  si.server_name = opt_.server_name;
  si.scene_name = scene_.scene_name;
  si.material_name = scene_.material_name;
  si.areal_density = scene_.areal_density;
  si.device_name = scene_.device.name;
  si.fingers = scene_.device.fingers;
  for (int k = 0; k < 3; ++k) {
    si.workspace_min[k] = scene_.device.workspace.min[k];
    si.workspace_max[k] = scene_.device.workspace.max[k];
    si.device_origin[k] = scene_.device_origin[k];
    for (int j = 0; j < 3; ++j) si.device_rotation[k][j] = scene_.device_rotation(k, j);
  }
  si.max_force = scene_.device.max_force;
  si.haptic_rate = scene_.haptic_rate;
  si.cloth_rate = opt_.cloth_rate;
  si.haptic_batch = opt_.haptic_batch;
  si.max_command_speed = opt_.max_command_speed;
  std::vector<std::string> topics(kTopicNames, kTopicNames + kTopics);
  topics.push_back("trajectory");
  topics.push_back("scene_request");
  si.num_topics = static_cast<int32_t>(topics.size());
  for (const auto& t : topics) {
    si.topics.push_back(t);
    si.key_expressions.push_back(t == "scene_request" ? "" : key_expression(opt_.server_name, t));
    si.lcm_channels.push_back(lcm_channel(t));
  }
  fill(scene_, si.topology);
  encode(si, scene_bytes_);

  if (opt_.zenoh) {
    zenoh_ = std::make_unique<ZenohSession>(opt_.zenoh_config, opt_.zenoh_listen);
    for (int t = 0; t < kTopics; ++t)
      zpub_[t] = std::make_unique<ZenohPublisher>(*zenoh_, key_expression(opt_.server_name, kTopicNames[t]));
    zcmd_ = std::make_unique<ZenohSubscriber>(
        *zenoh_, key_expression(opt_.server_name, "trajectory"),
        [this](const std::uint8_t* d, std::size_t n) { on_command_bytes(d, n); });
    zscene_ = std::make_unique<ZenohQueryable>(*zenoh_, key_expression(opt_.server_name, "scene"),
                                               [this] { return scene_bytes(); });
  }
  if (!opt_.lcm_url.empty()) {
    lcm_ = std::make_unique<LcmBus>(opt_.lcm_url);
    lcm_->subscribe(lcm_channel("trajectory"),
                    [this](const std::uint8_t* d, std::size_t n) { on_command_bytes(d, n); });
    lcm_->subscribe(lcm_channel("scene_request"), [this](const std::uint8_t*, std::size_t) {
      scene_requested_.store(true);
      wake_.notify_one();
    });
    lcm_->start();
  }
  if (!opt_.lcm_log.empty()) log_ = std::make_unique<LcmBus>(lcm_log_url(opt_.lcm_log));

  thread_ = std::thread([this] { run(); });
}

Hub::~Hub() {
  zcmd_.reset();    // no command callback runs after this
  zscene_.reset();
  post_event("stopped", "server " + opt_.server_name + " stops publishing");
  {
    std::lock_guard<std::mutex> lock(run_mu_);
    stop_ = true;
  }
  wake_.notify_one();
  if (thread_.joinable()) thread_.join();
  lcm_.reset();
  log_.reset();
  for (auto& p : zpub_) p.reset();
  zenoh_.reset();
}

// --- real-time side ------------------------------------------------------------------------

void Hub::on_sim_step(const haptics::ClothSnapshot& s) noexcept {
  const double period = 1.0 / opt_.cloth_rate;
  if (next_cloth_time_ >= 0.0 && s.time < next_cloth_time_ - 1e-9) return;
  next_cloth_time_ = std::max(next_cloth_time_ < 0.0 ? s.time : next_cloth_time_, s.time - period) + period;
  ClothFrame& f = cloth_.back();
  if (f.x.size() != s.x.size()) return;  // another mesh: never resize here
  f.time = s.time;
  f.step = s.step;
  for (std::size_t i = 0; i < s.x.size(); ++i) copy3(f.x[i], s.x[i]);
  cloth_.publish();
}

void Hub::on_haptic_tick(const haptics::HapticReport& r, const devices::DeviceState& state,
                         const devices::DeviceCommand& cmd) noexcept {
  const bool stale = (cmd.flags & devices::kFlagStale) != 0;
  if (stale && !was_stale_) watchdog_trips_.fetch_add(1, std::memory_order_relaxed);
  was_stale_ = stale;
  if (cmd.flags & devices::kFlagFault) nan_forces_.fetch_add(1, std::memory_order_relaxed);

  const std::uint64_t h = head_.load(std::memory_order_relaxed);
  if (h - tail_.load(std::memory_order_acquire) >= kRing) {
    ring_dropped_.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  HapticSample& s = ring_[h % kRing];
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
  head_.store(h + 1, std::memory_order_release);
}

void Hub::on_loop_stats(const haptics::LoopStats& s) noexcept {
  loop_.back() = summarize(s);
  loop_.publish();
}

// --- other threads ---------------------------------------------------------------------------

void Hub::post_event(const std::string& kind, const std::string& text) {
  {
    std::lock_guard<std::mutex> lock(ev_mu_);
    events_.push_back(Event{wall_utime(), kind, text});
  }
  wake_.notify_one();
}

void Hub::set_command_sink(devices::RemoteCommandSink* sink) {
  std::lock_guard<std::mutex> lock(sink_mu_);
  sink_ = sink;
  if (sink_) sink_->set_max_speed(max_speed_);
}

std::string Hub::handle_command(const hapticloth::trajectory_cmd_t& m) {
  devices::TrajectoryCommand c;
  std::string why = to_device_command(m, scene_, c);
  if (why.empty()) {
    std::lock_guard<std::mutex> lock(sink_mu_);
    why = sink_ ? sink_->submit(c) : "no remote device (run the server with --device remote)";
  }
  if (log_) {
    std::vector<std::uint8_t> bytes;
    encode(m, bytes);
    std::lock_guard<std::mutex> lock(ev_mu_);
    commands_to_log_.push_back(std::move(bytes));
  }
  const std::string who = "finger " + std::to_string(m.finger) + ", " + std::to_string(m.num_points) +
                          " points from '" + m.source + "' seq " + std::to_string(m.seq);
  if (why.empty()) {
    accepted_.fetch_add(1);
    post_event("command_accepted", who);
  } else {
    rejected_.fetch_add(1);
    post_event("command_rejected", who + ": " + why);
  }
  return why;
}

std::vector<std::uint8_t> Hub::scene_bytes() const { return scene_bytes_; }

HubStats Hub::stats() const {
  HubStats s;
  for (int t = 0; t < kTopics; ++t) {
    s.published[t] = published_[t].load();
    s.skipped[t] = skipped_[t].load();
  }
  s.commands_accepted = accepted_.load();
  s.commands_rejected = rejected_.load();
  s.haptic_samples_dropped = ring_dropped_.load();
  s.watchdog_trips = watchdog_trips_.load();
  s.nan_forces = nan_forces_.load();
  return s;
}

void Hub::flush() {
  std::unique_lock<std::mutex> lock(run_mu_);
  const std::uint64_t want = ++flush_request_;
  wake_.notify_one();
  flushed_.wait_for(lock, std::chrono::seconds(5), [&] { return flush_done_ >= want || stop_; });
}

// --- publisher thread ----------------------------------------------------------------------

void Hub::run() {
  const double period = std::clamp(std::min(opt_.haptic_batch, 1.0 / opt_.cloth_rate), 1e-3, 0.1);
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

bool Hub::wanted(Topic t) const {
  const auto& z = zpub_[static_cast<int>(t)];
  return (z && z->matching()) || lcm_ || log_;
}

void Hub::send(Topic t, const std::vector<std::uint8_t>& bytes) {
  const int i = static_cast<int>(t);
  if (zpub_[i] && zpub_[i]->matching()) zpub_[i]->put(bytes.data(), bytes.size());
  if (lcm_) lcm_->publish(channel_[i], bytes.data(), bytes.size());
  if (log_) log_->publish(channel_[i], bytes.data(), bytes.size());
  published_[i].fetch_add(1, std::memory_order_relaxed);
}

// A trajectory command as it arrives on either transport: decoded and handled, or rejected and
// counted with an event.
void Hub::on_command_bytes(const std::uint8_t* d, std::size_t n) {
  hapticloth::trajectory_cmd_t m;
  if (decode(d, n, m)) {
    handle_command(m);
    return;
  }
  rejected_.fetch_add(1);
  post_event("command_rejected", "malformed trajectory_cmd_t (" + std::to_string(n) + " bytes)");
}

// True if some transport wants topic t now; otherwise the message is counted as skipped.
bool Hub::admit(Topic t) {
  if (wanted(t)) return true;
  skipped_[static_cast<int>(t)].fetch_add(1);
  return false;
}

template <class M>
void Hub::send_msg(Topic t, const M& m) {
  encode(m, buf_);
  send(t, buf_);
}

void Hub::publish_scene() {
  if (admit(Topic::Scene)) send(Topic::Scene, scene_bytes_);
  if (admit(Topic::Topology)) {
    hapticloth::cloth_topology_t m;
    fill(scene_, m);
    send_msg(Topic::Topology, m);
  }
}

void Hub::publish_haptics() {
  const std::uint64_t h = head_.load(std::memory_order_acquire);
  std::uint64_t t = tail_.load(std::memory_order_relaxed);
  if (h == t) return;
  batch_.clear();
  for (; t != h; ++t) batch_.push_back(ring_[t % kRing]);
  tail_.store(t, std::memory_order_release);
  for (std::size_t k = 0; k < batch_.size(); k += kMaxSamplesPerMessage) {
    if (!admit(Topic::Haptics)) continue;
    const int n = static_cast<int>(std::min<std::size_t>(kMaxSamplesPerMessage, batch_.size() - k));
    fill(batch_.data() + k, n, fingers_, haptic_msg_);
    send_msg(Topic::Haptics, haptic_msg_);
  }
}

void Hub::publish_events() {
  std::deque<Event>& ev = events_out_;
  std::deque<std::vector<std::uint8_t>>& cmds = commands_out_;
  {
    std::lock_guard<std::mutex> lock(ev_mu_);
    if (events_.empty() && commands_to_log_.empty()) return;  // the idle path allocates nothing
    ev.swap(events_);
    cmds.swap(commands_to_log_);
  }
  for (const auto& c : cmds)
    if (log_) log_->publish(lcm_channel("trajectory"), c.data(), c.size());
  for (const auto& e : ev) {
    if (!admit(Topic::Events)) continue;
    hapticloth::event_t m;
    m.utime = e.utime;
    m.kind = e.kind;
    m.text = e.text;
    m.watchdog_trips = static_cast<int64_t>(watchdog_trips_.load());
    m.nan_forces = static_cast<int64_t>(nan_forces_.load());
    m.dropped_packets = static_cast<int64_t>(dropped_packets_.load());
    m.rejected_commands = static_cast<int64_t>(rejected_.load());
    send_msg(Topic::Events, m);
  }
  ev.clear();
  cmds.clear();
}

void Hub::publish_pending() {
  if (scene_requested_.exchange(false)) publish_scene();

  if (cloth_.acquire() && admit(Topic::Cloth)) {
    const ClothFrame& f = cloth_.front();
    cloth_msg_.utime = wall_utime();
    cloth_msg_.time = f.time;
    cloth_msg_.step = static_cast<int64_t>(f.step);
    cloth_msg_.num_vertices = static_cast<int32_t>(f.x.size());
    cloth_msg_.positions.resize(f.x.size());
    for (std::size_t i = 0; i < f.x.size(); ++i) cloth_msg_.positions[i].assign(f.x[i].begin(), f.x[i].end());
    send_msg(Topic::Cloth, cloth_msg_);
  }

  publish_haptics();

  if (loop_.acquire() && admit(Topic::Stats)) {
    hapticloth::loop_stats_t m;
    fill(loop_.front(), m);
    send_msg(Topic::Stats, m);
  }

  // Faults the haptic loop counted: one event per new batch of them.
  const std::uint64_t w = watchdog_trips_.load(), n = nan_forces_.load(), d = dropped_packets_.load();
  if (w > seen_watchdog_)
    post_event("watchdog", "device state went stale " + std::to_string(w - seen_watchdog_) +
                               " time(s); forces ramped out");
  if (n > seen_nan_)
    post_event("nan", std::to_string(n - seen_nan_) + " non-finite force(s) replaced by zero");
  if (d > seen_dropped_)
    post_event("dropped_packets", std::to_string(d - seen_dropped_) + " device packet(s) dropped");
  seen_watchdog_ = w;
  seen_nan_ = n;
  seen_dropped_ = d;

  publish_events();
}

std::unique_ptr<Hub> make_hub(const TransportOptions& opt, const SceneInfo& scene) {
  return std::make_unique<Hub>(opt, scene);
}

}  // namespace hapticloth::transport
