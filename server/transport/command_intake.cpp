#include "transport/command_intake.hpp"

namespace hapticloth::transport {

CommandIntake::CommandIntake(const SceneInfo& scene, double max_speed, HubEvents& events, bool log)
    : scene_(scene), max_speed_(max_speed), events_(events), log_(log) {}

void CommandIntake::set_sink(devices::RemoteCommandSink* sink) {
  std::lock_guard<std::mutex> lock(sink_mu_);
  sink_ = sink;
  if (sink_) sink_->set_max_speed(max_speed_);
}

std::string CommandIntake::handle(const hapticloth::trajectory_cmd_t& m, bool live) {
  devices::TrajectoryCommand c;
  std::string why = live ? to_device_command(m, scene_, c)
                         : "the session has not started (the server is settling its cloth)";
  if (why.empty()) {
    std::lock_guard<std::mutex> lock(sink_mu_);
    why = sink_ ? sink_->submit(c) : "no remote device (run the server with --device remote)";
  }
  if (log_) {
    std::vector<std::uint8_t> bytes;
    encode(m, bytes);
    events_.queue_for_log(std::move(bytes));
  }
  const std::string who = "finger " + std::to_string(m.finger) + ", " + std::to_string(m.num_points) +
                          " points from '" + m.source + "' seq " + std::to_string(m.seq);
  if (why.empty()) {
    accepted_.fetch_add(1);
    events_.post("command_accepted", who);
  } else {
    rejected_.fetch_add(1);
    events_.post("command_rejected", who + ": " + why);
  }
  return why;
}

void CommandIntake::on_bytes(const std::uint8_t* d, std::size_t n, bool live) {
  hapticloth::trajectory_cmd_t m;
  if (decode(d, n, m)) {
    handle(m, live);
    return;
  }
  rejected_.fetch_add(1);
  events_.post("command_rejected", "malformed trajectory_cmd_t (" + std::to_string(n) + " bytes)");
}

}  // namespace hapticloth::transport
