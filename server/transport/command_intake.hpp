// Trajectory commands from clients, as either transport receives them: decoded (or rejected as
// malformed), converted to the device frame and checked (to_device_command), handed to the
// remote device, queued for the log, counted, and announced as events.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <string>

#include "remote/command_sink.hpp"
#include "transport/codec.hpp"
#include "transport/hub_events.hpp"
#include "transport/scene_info.hpp"

namespace hapticloth::transport {

class CommandIntake {
 public:
  /// `scene`, `events` must outlive the intake. `log`: queue every command for the log.
  CommandIntake(const SceneInfo& scene, double max_speed, HubEvents& events, bool log);

  /// Where commands go (nullptr: rejected, "no remote device"); sets its speed limit.
  void set_sink(devices::RemoteCommandSink* sink);
  /// Returns "" if accepted, else the reason (also a "command_rejected" event). Before the
  /// session (`live` false) every command is rejected: the server is settling its cloth.
  std::string handle(const hapticloth::trajectory_cmd_t& m, bool live = true);
  /// A command's bytes as they arrive: decoded and handled, or rejected, counted, with an event.
  void on_bytes(const std::uint8_t* d, std::size_t n, bool live = true);

  std::uint64_t accepted() const { return accepted_.load(); }
  std::uint64_t rejected() const { return rejected_.load(); }

 private:
  const SceneInfo& scene_;
  const double max_speed_;
  HubEvents& events_;
  const bool log_;
  std::mutex sink_mu_;
  devices::RemoteCommandSink* sink_ = nullptr;
  std::atomic<std::uint64_t> accepted_{0}, rejected_{0};
};

}  // namespace hapticloth::transport
