// The Hub's publisher thread: at the haptic batch period (or the cloth period, if shorter) it
// takes what the mailboxes, the events and the scene requests hold, encodes it and sends it on
// the transports. The only thread that encodes; it never blocks the loops.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <thread>
#include <vector>

#include "transport/command_intake.hpp"
#include "transport/hub_events.hpp"
#include "transport/hub_transports.hpp"
#include "transport/loop_mailboxes.hpp"
#include "transport/options.hpp"
#include "transport/scene_messages.hpp"

namespace hapticloth::transport {

class HubPublisher {
 public:
  /// Starts the thread. Everything given must outlive the publisher (or its stop()).
  HubPublisher(const TransportOptions& opt, SceneMessages& scene, LoopMailboxes& loops,
               HubEvents& events, const CommandIntake& commands, HubTransports& out);
  ~HubPublisher();
  HubPublisher(const HubPublisher&) = delete;
  HubPublisher& operator=(const HubPublisher&) = delete;

  /// Publishes everything pending now and returns when done (at most 5 s).
  void flush();
  /// Publishes what is left and ends the thread.
  void stop();

 private:
  void run(double period);
  void publish_pending();
  void publish_scene();
  void publish_cloth();
  void fill_refined(const LoopMailboxes::ClothFrame& f);
  void publish_haptics();
  void publish_tactile();
  void publish_stats();
  void publish_events();
  template <class M>
  void send_msg(Topic t, const M& m);

  SceneMessages& scene_;
  LoopMailboxes& loops_;
  HubEvents& events_;
  const CommandIntake& commands_;
  HubTransports& out_;

  // Publisher thread only.
  std::vector<std::uint8_t> buf_;
  std::vector<HapticSample> batch_;
  std::vector<TactileSample> tactile_batch_;
  hapticloth::cloth_state_t cloth_msg_;
  hapticloth::haptic_state_t haptic_msg_;
  hapticloth::tactile_state_t tactile_msg_;
  std::deque<HubEvents::Event> events_out_;
  std::deque<std::vector<std::uint8_t>> commands_out_;

  std::mutex run_mu_;
  std::condition_variable wake_, flushed_;
  bool stop_ = false;
  std::uint64_t flush_request_ = 0, flush_done_ = 0;
  std::thread thread_;
};

}  // namespace hapticloth::transport
