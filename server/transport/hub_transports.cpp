#include "transport/hub_transports.hpp"

#include <sys/stat.h>

#include "transport/codec.hpp"
#include "transport/foxglove_sink.hpp"
#include "transport/lcm_bus.hpp"
#include "transport/zenoh_session.hpp"

namespace hapticloth::transport {

HubTransports::HubTransports(const TransportOptions& opt, Inputs in) {
  for (int t = 0; t < kTopics; ++t) channel_[t] = lcm_channel(topic_name(static_cast<Topic>(t)));
  if (opt.zenoh) {
    zenoh_ = std::make_unique<ZenohSession>(opt.zenoh_config, opt.zenoh_listen);
    for (int t = 0; t < kTopics; ++t)
      zpub_[t] = std::make_unique<ZenohPublisher>(
          *zenoh_, key_expression(opt.server_name, topic_name(static_cast<Topic>(t))));
    zcmd_ = std::make_unique<ZenohSubscriber>(*zenoh_, key_expression(opt.server_name, "trajectory"),
                                              in.command);
    zscene_ = std::make_unique<ZenohQueryable>(*zenoh_, key_expression(opt.server_name, "scene"),
                                               in.scene);
  }
  if (!opt.lcm_url.empty()) {
    lcm_ = std::make_unique<LcmBus>(opt.lcm_url);
    lcm_->subscribe(lcm_channel("trajectory"), in.command);
    lcm_->subscribe(lcm_channel("scene_request"),
                    [request = in.scene_request](const std::uint8_t*, std::size_t) { request(); });
    lcm_->start();
  }
  if (!opt.lcm_log.empty()) log_ = std::make_unique<LcmBus>(lcm_log_url(opt.lcm_log));
  log_path_ = opt.lcm_log;
  if (!opt.foxglove.empty() || !opt.mcap.empty())
    fox_ = std::make_unique<FoxgloveSink>(
        FoxgloveOptions{opt.foxglove, opt.mcap, opt.server_name, opt.finger_radius});
}

HubTransports::~HubTransports() { close(); }

void HubTransports::close_inputs() {
  zcmd_.reset();
  zscene_.reset();
}

std::string HubTransports::close() {
  close_inputs();
  lcm_.reset();
  log_.reset();
  if (fox_) {
    try {
      fox_->close();
    } catch (const std::runtime_error& e) {
      fox_error_ = e.what();
    }
  }
  for (auto& p : zpub_) p.reset();
  zenoh_.reset();
  std::string lost = fox_error_;
  if (!log_path_.empty()) {
    struct stat st {};
    const std::uint64_t want = log_bytes_.load();
    const std::uint64_t have = ::stat(log_path_.c_str(), &st) == 0 && S_ISREG(st.st_mode)
                                   ? static_cast<std::uint64_t>(st.st_size) : 0;
    if (have < want)
      lost += (lost.empty() ? "" : "; ") + std::string("LCM log ") + log_path_ + ": " + std::to_string(have) +
              " of " + std::to_string(want) + " bytes written; messages could not be written (the disk is "
              "full or the file failed)";
  }
  return lost;
}

void HubTransports::log(const std::string& channel, const std::vector<std::uint8_t>& bytes) {
  constexpr std::uint64_t kEventHeader = 4 + 8 + 8 + 4 + 4;  // sync, number, time, lengths
  log_bytes_.fetch_add(kEventHeader + channel.size() + bytes.size());
  log_->publish(channel, bytes.data(), bytes.size());
}

bool HubTransports::wanted(Topic t) const {
  const auto& z = zpub_[static_cast<int>(t)];
  return (z && z->matching()) || lcm_ || log_ || (fox_ && fox_->wants(t));
}

bool HubTransports::admit(Topic t) {
  if (wanted(t)) return true;
  skipped_[static_cast<int>(t)].fetch_add(1);
  return false;
}

void HubTransports::send(Topic t, const std::vector<std::uint8_t>& bytes) {
  const int i = static_cast<int>(t);
  if (zpub_[i] && zpub_[i]->matching()) zpub_[i]->put(bytes.data(), bytes.size());
  if (lcm_) lcm_->publish(channel_[i], bytes.data(), bytes.size());
  if (log_) log(channel_[i], bytes);
  if (fox_ && fox_->wants(t)) fox_->send(t, bytes.data(), bytes.size(), wall_utime());
  published_[i].fetch_add(1, std::memory_order_relaxed);
}

void HubTransports::log_command(const std::vector<std::uint8_t>& bytes) {
  if (log_) log(lcm_channel("trajectory"), bytes);
}

}  // namespace hapticloth::transport
