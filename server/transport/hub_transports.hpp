// The transports a Hub owns: a zenoh session with a publisher per topic, the trajectory
// subscriber and the scene queryable; an LCM provider, which also takes trajectory commands and
// scene requests; an LCM log file; the Foxglove live view and MCAP recording. Nothing is sent
// on a topic nobody can receive.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "transport/options.hpp"
#include "transport/topics.hpp"

namespace hapticloth::transport {

class ZenohSession;
class ZenohPublisher;
class ZenohSubscriber;
class ZenohQueryable;
class LcmBus;
class FoxgloveSink;

class HubTransports {
 public:
  /// What comes in, called on the transports' own threads: trajectory_cmd_t bytes (zenoh or
  /// LCM), an LCM scene_request_t, and the bytes the scene queryable answers with.
  struct Inputs {
    std::function<void(const std::uint8_t*, std::size_t)> command;
    std::function<void()> scene_request;
    std::function<std::vector<std::uint8_t>()> scene;
  };

  /// Opens what `opt` asks for. Throws std::runtime_error naming the transport that cannot be
  /// opened (zenoh listen endpoint in use, bad config file, unwritable log, bad LCM URL).
  HubTransports(const TransportOptions& opt, Inputs in);
  ~HubTransports();
  HubTransports(const HubTransports&) = delete;
  HubTransports& operator=(const HubTransports&) = delete;

  /// No zenoh input callback runs once this returns.
  void close_inputs();
  /// Closes everything (LCM first: its receive thread ends here; the MCAP file is finished).
  /// Also done by the destructor. Returns "" or what was lost: the MCAP file not finished, LCM
  /// log messages not written (a full disk, a failing file).
  std::string close();

  /// True if some transport wants topic t now (a matching zenoh subscriber, an LCM provider or
  /// the log); otherwise the message is counted as skipped.
  bool admit(Topic t);
  /// Sends on every transport that wants it, counted as published.
  void send(Topic t, const std::vector<std::uint8_t>& bytes);
  /// A trajectory command as received, to the log only (none: dropped).
  void log_command(const std::vector<std::uint8_t>& bytes);
  bool logging() const { return log_ != nullptr; }
  /// The Foxglove live view and recording, or null.
  const FoxgloveSink* foxglove() const { return fox_.get(); }

  /// Any thread.
  std::uint64_t published(Topic t) const { return published_[static_cast<int>(t)].load(); }
  std::uint64_t skipped(Topic t) const { return skipped_[static_cast<int>(t)].load(); }

 private:
  bool wanted(Topic t) const;

  std::unique_ptr<ZenohSession> zenoh_;
  std::array<std::unique_ptr<ZenohPublisher>, kTopics> zpub_;
  std::unique_ptr<ZenohSubscriber> zcmd_;
  std::unique_ptr<ZenohQueryable> zscene_;
  std::unique_ptr<LcmBus> lcm_, log_;
  std::unique_ptr<FoxgloveSink> fox_;
  std::string fox_error_;  // the recording could not be finished (close)
  void log(const std::string& channel, const std::vector<std::uint8_t>& bytes);
  std::string log_path_;
  // LCM's file provider does not report a failed write (publish returns 0 either way): the log
  // must hold, once closed, the bytes of every event given to it (28-byte header, channel,
  // data), else some were lost.
  std::atomic<std::uint64_t> log_bytes_{0};
  std::array<std::string, kTopics> channel_;
  std::array<std::atomic<std::uint64_t>, kTopics> published_{}, skipped_{};
};

}  // namespace hapticloth::transport
