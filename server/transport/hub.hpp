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
// Inputs:
//   trajectory hapticloth/<server>/trajectory  HAPTICLOTH_TRAJECTORY    trajectory_cmd_t
//   -                                          HAPTICLOTH_SCENE_REQUEST scene_request_t
//
// Threads: the session's loops call the SessionObserver methods, which only copy into
// preallocated mailboxes (a latest-value triple buffer for the cloth and the loop statistics,
// a single-producer ring for the haptic samples): no lock, no allocation. The Hub's own
// publisher thread encodes and sends. Nothing is encoded for a topic nobody can receive: no
// matching zenoh subscriber, no LCM provider and no log. zenoh puts drop under congestion
// instead of blocking, so a stalled client never holds up the publisher, let alone the loops.
#pragma once

#include <array>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "haptics/observer.hpp"
#include "hal/rt_handoff.hpp"
#include "remote/command_sink.hpp"
#include "transport/codec.hpp"
#include "transport/options.hpp"
#include "transport/scene_info.hpp"

namespace hapticloth::transport {

class ZenohSession;
class ZenohPublisher;
class ZenohSubscriber;
class ZenohQueryable;
class LcmBus;

enum class Topic : int { Topology, Cloth, Haptics, Stats, Events, Scene };
inline constexpr int kTopics = 6;
const char* topic_name(Topic t);
/// hapticloth/<server>/<topic>
std::string key_expression(const std::string& server, const std::string& topic);
/// HAPTICLOTH_<TOPIC>
std::string lcm_channel(const std::string& topic);

struct HubStats {
  std::array<std::uint64_t, kTopics> published{};  ///< messages sent, per topic
  std::array<std::uint64_t, kTopics> skipped{};    ///< not encoded: nobody could receive them
  std::uint64_t commands_accepted = 0, commands_rejected = 0;
  std::uint64_t haptic_samples_dropped = 0;        ///< ring full (publisher behind)
  std::uint64_t watchdog_trips = 0, nan_forces = 0;
};

class Hub : public haptics::SessionObserver {
 public:
  /// Opens the transports the options ask for and starts the publisher thread. Throws
  /// std::runtime_error naming the transport that cannot be opened (zenoh listen endpoint in
  /// use, bad config file, unwritable log, bad LCM URL).
  Hub(const TransportOptions& opt, SceneInfo scene);
  ~Hub() override;
  Hub(const Hub&) = delete;
  Hub& operator=(const Hub&) = delete;

  // SessionObserver: real-time safe (copies into preallocated mailboxes).
  void on_sim_step(const haptics::ClothSnapshot& s) noexcept override;
  void on_haptic_tick(const haptics::HapticReport& r, const devices::DeviceState& state,
                      const devices::DeviceCommand& cmd) noexcept override;
  void on_loop_stats(const haptics::LoopStats& s) noexcept override;

  /// Any thread but the real-time ones. Publishes an event_t (kind, text, the counters).
  void post_event(const std::string& kind, const std::string& text);
  /// Where trajectory commands go (nullptr: they are rejected, "no remote device"). The sink
  /// must outlive the Hub or be reset to nullptr first. Also sets its speed limit from the
  /// options.
  void set_command_sink(devices::RemoteCommandSink* sink);
  /// The device driver's dropped-packet total, carried in later events.
  void note_dropped_packets(std::uint64_t total) { dropped_packets_.store(total); }
  /// Handles a trajectory command as if it had arrived (both transports call this). Returns ""
  /// if accepted, else the reason (also published as a "command_rejected" event).
  std::string handle_command(const hapticloth::trajectory_cmd_t& m);

  /// Publishes everything pending now and returns when done (tests, shutdown).
  void flush();
  HubStats stats() const;
  const TransportOptions& options() const { return opt_; }
  const SceneInfo& scene() const { return scene_; }
  /// The encoded scene_info_t the queryable answers.
  std::vector<std::uint8_t> scene_bytes() const;

 private:
  struct Event {
    std::int64_t utime;
    std::string kind, text;
  };
  struct ClothFrame {
    double time = -1.0;
    std::uint64_t step = 0;
    std::vector<std::array<float, 3>> x;
  };
  static constexpr std::size_t kRing = 4096;  // haptic samples (4 s at 1 kHz)

  void run();
  void publish_pending();
  void publish_scene();
  void publish_haptics();
  void publish_events();
  bool wanted(Topic t) const;
  bool admit(Topic t);
  void on_command_bytes(const std::uint8_t* d, std::size_t n);
  void send(Topic t, const std::vector<std::uint8_t>& bytes);
  template <class M>
  void send_msg(Topic t, const M& m);

  TransportOptions opt_;
  SceneInfo scene_;
  int fingers_;
  double max_speed_ = 1.0;

  // Transports (declared before the mailboxes they feed from; destroyed after the thread).
  std::unique_ptr<ZenohSession> zenoh_;
  std::array<std::unique_ptr<ZenohPublisher>, kTopics> zpub_;
  std::unique_ptr<ZenohSubscriber> zcmd_;
  std::unique_ptr<ZenohQueryable> zscene_;
  std::unique_ptr<LcmBus> lcm_, log_;
  std::array<std::string, kTopics> channel_;

  // Mailboxes from the loops.
  haptics::TripleBuffer<ClothFrame> cloth_;
  double next_cloth_time_ = -1.0;  // sim thread only
  haptics::TripleBuffer<LoopSummary> loop_;
  std::vector<HapticSample> ring_;
  std::atomic<std::uint64_t> head_{0}, tail_{0};
  std::uint64_t last_tick_ = 0;     // haptic thread only
  // The gate starts stale (no device sample yet), and counts a trip on each fresh -> stale
  // transition; so does this (the summary's stale events and the watchdog events agree).
  bool was_stale_ = true;           // haptic thread only
  std::atomic<std::uint64_t> ring_dropped_{0}, watchdog_trips_{0}, nan_forces_{0};
  std::atomic<std::uint64_t> dropped_packets_{0};

  // From other threads.
  std::mutex ev_mu_;
  std::deque<Event> events_;
  std::deque<std::vector<std::uint8_t>> commands_to_log_;
  std::atomic<bool> scene_requested_{true};
  std::mutex sink_mu_;
  devices::RemoteCommandSink* sink_ = nullptr;

  // Publisher thread.
  std::deque<Event> events_out_;
  std::deque<std::vector<std::uint8_t>> commands_out_;
  std::vector<std::uint8_t> scene_bytes_;
  std::vector<std::uint8_t> buf_;
  std::vector<HapticSample> batch_;
  hapticloth::cloth_state_t cloth_msg_;
  hapticloth::haptic_state_t haptic_msg_;
  std::uint64_t seen_watchdog_ = 0, seen_nan_ = 0, seen_dropped_ = 0;
  std::array<std::atomic<std::uint64_t>, kTopics> published_{}, skipped_{};
  std::atomic<std::uint64_t> accepted_{0}, rejected_{0};
  std::mutex run_mu_;
  std::condition_variable wake_;
  bool stop_ = false;
  std::uint64_t flush_request_ = 0, flush_done_ = 0;
  std::condition_variable flushed_;
  std::thread thread_;
};

/// The Hub, or throws (see Hub::Hub).
std::unique_ptr<Hub> make_hub(const TransportOptions& opt, const SceneInfo& scene);

}  // namespace hapticloth::transport
