#include "transport/hub.hpp"

#include <stdexcept>

namespace hapticloth::transport {

namespace {
// The options and the device the Hub is built for, or throws std::invalid_argument (bad input,
// never the fall-back to running without zenoh that a zenoh endpoint in use gets).
const TransportOptions& checked(const TransportOptions& opt, const SceneInfo& scene) {
  if (const std::string e = server_name_error(opt.server_name); !e.empty())
    throw std::invalid_argument("transport: server name " + e);
  if (!(opt.cloth_rate > 0.0) || !(opt.haptic_batch > 0.0))
    throw std::invalid_argument("transport: cloth rate and haptic batch must be positive");
  if (const std::string e = devices::validate(scene.device); !e.empty())
    throw std::invalid_argument("transport: device " + e);
  return opt;
}
}  // namespace

Hub::Hub(const TransportOptions& opt, SceneInfo scene)
    : live_(!opt.hold_until_session),
      opt_(checked(opt, scene)),
      scene_(std::move(scene)),
      messages_(opt_, scene_),
      commands_(scene_, opt_.max_command_speed, events_, !opt_.lcm_log.empty()),
      loops_(scene_.rest_positions.size(), scene_.device, opt_.cloth_rate, scene_.weft_period, scene_.warp_period),
      transports_(opt_, HubTransports::Inputs{
                            [this](const std::uint8_t* d, std::size_t n) { commands_.on_bytes(d, n, live_.load()); },
                            [this] { if (live_.load()) messages_.request(); },
                            [this] { return live_.load() ? messages_.info_bytes() : std::vector<std::uint8_t>{}; }}),
      publisher_(opt_, messages_, loops_, events_, commands_, transports_) {}

Hub::~Hub() { finish(); }

std::string Hub::finish() {
  if (finished_) return finish_error_;
  finished_ = true;
  transports_.close_inputs();  // no zenoh command callback runs after this
  post_event("stopped", "server " + opt_.server_name + " stops publishing");
  publisher_.stop();                     // the last samples, statistics and events
  finish_error_ = transports_.close();   // and LCM's receive thread; the MCAP file finished
  return finish_error_;
}

void Hub::on_sim_step(const haptics::ClothSnapshot& s) noexcept { loops_.put_cloth(s); }

void Hub::on_refined(const haptics::RefinedRegions& r) noexcept { loops_.put_refined(r); }

void Hub::on_haptic_tick(const haptics::HapticReport& r, const devices::DeviceState& state,
                         const devices::DeviceCommand& cmd) noexcept {
  loops_.put_tick(r, state, cmd);
}

void Hub::on_loop_stats(const haptics::LoopStats& s) noexcept { loops_.put_stats(s); }

void Hub::on_tactile(const haptics::HapticReport& r, const haptics::TactileRendering& t,
                     const devices::TactileCommand& out) noexcept {
  loops_.put_tactile(r, t, out);
}

HubStats Hub::stats() const {
  HubStats s;
  for (int t = 0; t < kTopics; ++t) {
    s.published[t] = transports_.published(static_cast<Topic>(t));
    s.skipped[t] = transports_.skipped(static_cast<Topic>(t));
  }
  s.commands_accepted = commands_.accepted();
  s.commands_rejected = commands_.rejected();
  s.haptic_samples_dropped = loops_.samples_dropped();
  s.tactile_samples_dropped = loops_.tactile_dropped();
  s.watchdog_trips = loops_.watchdog_trips();
  s.nan_forces = loops_.nan_forces();
  return s;
}

std::unique_ptr<Hub> make_hub(const TransportOptions& opt, const SceneInfo& scene) {
  return std::make_unique<Hub>(opt, scene);
}

}  // namespace hapticloth::transport
