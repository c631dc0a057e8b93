// The Hub's events (event_t): posted from any thread but the real-time ones, and the
// trajectory commands waiting for the log, both queued under one lock and taken by the
// publisher thread in one swap. Also turns the faults the loops and the device driver count
// into events.
#pragma once

#include <atomic>
#include <cstdint>
#include <deque>
#include <mutex>
#include <string>
#include <vector>

namespace hapticloth::transport {

class HubEvents {
 public:
  struct Event {
    std::int64_t utime;  ///< us since the Unix epoch, when posted
    std::string kind, text;
  };

  /// Any thread but the real-time ones.
  void post(const std::string& kind, const std::string& text);
  /// A trajectory command as received (encoded), for the log.
  void queue_for_log(std::vector<std::uint8_t> command);
  /// The device driver's dropped-packet total (any thread).
  void note_dropped_packets(std::uint64_t total) { dropped_packets_.store(total); }
  std::uint64_t dropped_packets() const { return dropped_packets_.load(); }

  /// Publisher thread: an event per fault kind that grew since the last call (device state gone
  /// stale, non-finite forces, dropped device packets).
  void post_faults(std::uint64_t watchdog_trips, std::uint64_t nan_forces);
  /// Publisher thread: swaps what was posted into the (empty) `events` and `commands`. False,
  /// taking and allocating nothing, if nothing was posted.
  bool take(std::deque<Event>& events, std::deque<std::vector<std::uint8_t>>& commands);

 private:
  std::mutex mu_;
  std::deque<Event> events_;
  std::deque<std::vector<std::uint8_t>> commands_;
  std::atomic<std::uint64_t> dropped_packets_{0};
  std::uint64_t seen_watchdog_ = 0, seen_nan_ = 0, seen_dropped_ = 0;  // publisher thread only
};

}  // namespace hapticloth::transport
