// The Hub: publishes a running session's state over zenoh and LCM, answers the scene for late
// joiners, and hands trajectory commands from clients to the remote device.
//
// Topics (proto/*.lcm; the same LCM-encoded bytes on both transports):
//   topic      zenoh key expression            LCM channel              message
//   topology   hapticloth/<server>/topology    HAPTICLOTH_TOPOLOGY      cloth_topology_t (start, request)
//   cloth      hapticloth/<server>/cloth       HAPTICLOTH_CLOTH         cloth_state_t (cloth_rate)
//   haptics    hapticloth/<server>/haptics     HAPTICLOTH_HAPTICS       haptic_state_t (every haptic_batch)
//   stats      hapticloth/<server>/stats       HAPTICLOTH_STATS         loop_stats_t (~1 Hz)
//   events     hapticloth/<server>/events      HAPTICLOTH_EVENTS        event_t
//   scene      hapticloth/<server>/scene       HAPTICLOTH_SCENE         scene_info_t (start, request;
//                                                                       zenoh: also a queryable)
//   tactile    hapticloth/<server>/tactile     HAPTICLOTH_TACTILE       tactile_state_t (every haptic_batch;
//                                                                       a device with a tactile display)
// Inputs:
//   trajectory hapticloth/<server>/trajectory  HAPTICLOTH_TRAJECTORY    trajectory_cmd_t
//   -                                          HAPTICLOTH_SCENE_REQUEST scene_request_t
//
// Threads: the session's loops call the SessionObserver methods, which only copy into
// preallocated mailboxes (LoopMailboxes: no lock, no allocation). The Hub's own publisher
// thread (HubPublisher) encodes and sends. Nothing is encoded for a topic nobody can receive:
// no matching zenoh subscriber, no LCM provider and no log. zenoh puts drop under congestion
// instead of blocking, so a stalled client never holds up the publisher, let alone the loops.
//
// The rooms: scene_messages (scene_info_t, topology), hub_transports (zenoh, LCM, log),
// loop_mailboxes (the loops' handoff), hub_publisher (the thread), command_intake (trajectory
// commands), hub_events (event_t); the Hub wires them and keeps the interface below.
#pragma once

#include <array>
#include <cstdint>
#include <atomic>
#include <memory>
#include <string>
#include <vector>

#include "haptics/observer.hpp"
#include "remote/command_sink.hpp"
#include "transport/codec.hpp"
#include "transport/command_intake.hpp"
#include "transport/hub_events.hpp"
#include "transport/hub_publisher.hpp"
#include "transport/hub_transports.hpp"
#include "transport/loop_mailboxes.hpp"
#include "transport/options.hpp"
#include "transport/scene_info.hpp"
#include "transport/scene_messages.hpp"
#include "transport/topics.hpp"

namespace hapticloth::transport {

struct HubStats {
  std::array<std::uint64_t, kTopics> published{};  ///< messages sent, per topic
  std::array<std::uint64_t, kTopics> skipped{};    ///< not encoded: nobody could receive them
  std::uint64_t commands_accepted = 0, commands_rejected = 0;
  std::uint64_t haptic_samples_dropped = 0;        ///< ring full (publisher behind)
  std::uint64_t tactile_samples_dropped = 0;       ///< the same, tactile ticks
  std::uint64_t watchdog_trips = 0, nan_forces = 0;
};

class Hub : public haptics::SessionObserver {
 public:
  /// Opens the transports the options ask for and starts the publisher thread. Throws
  /// std::runtime_error naming what is wrong: a bad server name, rate or device (devices::
  /// validate), or a transport that cannot be opened (zenoh listen endpoint in use, bad config
  /// file, unwritable log, bad LCM URL).
  Hub(const TransportOptions& opt, SceneInfo scene);
  ~Hub() override;
  Hub(const Hub&) = delete;
  Hub& operator=(const Hub&) = delete;

  // SessionObserver: real-time safe (copies into preallocated mailboxes).
  void on_sim_step(const haptics::ClothSnapshot& s) noexcept override;
  void on_refined(const haptics::RefinedRegions& r) noexcept override;
  void on_haptic_tick(const haptics::HapticReport& r, const devices::DeviceState& state,
                      const devices::DeviceCommand& cmd) noexcept override;
  void on_loop_stats(const haptics::LoopStats& s) noexcept override;
  void on_tactile(const haptics::HapticReport& r, const haptics::TactileRendering& t,
                  const devices::TactileCommand& out) noexcept override;

  /// Any thread but the real-time ones. Publishes an event_t (kind, text, the counters).
  void post_event(const std::string& kind, const std::string& text) { events_.post(kind, text); }
  /// Where trajectory commands go (nullptr: they are rejected, "no remote device"). The sink
  /// must outlive the Hub or be reset to nullptr first. Also sets its speed limit from the
  /// options.
  void set_command_sink(devices::RemoteCommandSink* sink) { commands_.set_sink(sink); }
  /// The device driver's dropped-packet total, carried in later events.
  void note_dropped_packets(std::uint64_t total) { events_.note_dropped_packets(total); }
  /// Handles a trajectory command as if it had arrived (both transports call this). Returns ""
  /// if accepted, else the reason (also published as a "command_rejected" event).
  std::string handle_command(const hapticloth::trajectory_cmd_t& m) { return commands_.handle(m, live_.load()); }

  /// With TransportOptions::hold_until_session (the server opens its Hub before the preroll,
  /// so that a bad endpoint is found at once), the Hub is there for clients from this call on:
  /// the scene is published and answered, commands are taken. Until then a scene query gets no
  /// answer and a command is rejected ("the session has not started"), as when the endpoint
  /// was not open yet.
  void session_started() {
    live_.store(true);
    messages_.request();
  }

  /// Publishes everything pending now and returns when done (tests, shutdown).
  void flush() { publisher_.flush(); }
  /// Ends publishing: the "stopped" event, the last messages, the transports closed (the MCAP
  /// file finished). Returns "" or why the MCAP file could not be finished. Also done by the
  /// destructor; stats() stay readable after it.
  std::string finish();
  /// The Foxglove live view and recording (counts per channel), or null.
  const FoxgloveSink* foxglove() const { return transports_.foxglove(); }
  HubStats stats() const;
  const TransportOptions& options() const { return opt_; }
  const SceneInfo& scene() const { return scene_; }

 private:
  // In the order they are built; the transports' input callbacks reach the parts before them,
  // and the publisher all of them, so it is built last (its thread stops first).
  std::atomic<bool> live_;  // answering clients (hold_until_session, session_started)
  TransportOptions opt_;
  SceneInfo scene_;
  SceneMessages messages_;
  HubEvents events_;
  CommandIntake commands_;
  LoopMailboxes loops_;
  HubTransports transports_;
  HubPublisher publisher_;
  bool finished_ = false;
  std::string finish_error_;
};

/// The Hub, or throws (see Hub::Hub).
std::unique_ptr<Hub> make_hub(const TransportOptions& opt, const SceneInfo& scene);

}  // namespace hapticloth::transport
