#include "transport/hub_events.hpp"

#include "transport/codec.hpp"

namespace hapticloth::transport {

void HubEvents::post(const std::string& kind, const std::string& text) {
  std::lock_guard<std::mutex> lock(mu_);
  events_.push_back(Event{wall_utime(), kind, text});
}

void HubEvents::queue_for_log(std::vector<std::uint8_t> command) {
  std::lock_guard<std::mutex> lock(mu_);
  commands_.push_back(std::move(command));
}

void HubEvents::post_faults(std::uint64_t watchdog_trips, std::uint64_t nan_forces) {
  const std::uint64_t w = watchdog_trips, n = nan_forces, d = dropped_packets_.load();
  if (w > seen_watchdog_)
    post("watchdog", "device state went stale " + std::to_string(w - seen_watchdog_) +
                         " time(s); forces ramped out");
  if (n > seen_nan_) post("nan", std::to_string(n - seen_nan_) + " non-finite force(s) replaced by zero");
  if (d > seen_dropped_)
    post("dropped_packets", std::to_string(d - seen_dropped_) + " device packet(s) dropped");
  seen_watchdog_ = w;
  seen_nan_ = n;
  seen_dropped_ = d;
}

bool HubEvents::take(std::deque<Event>& events, std::deque<std::vector<std::uint8_t>>& commands) {
  std::lock_guard<std::mutex> lock(mu_);
  if (events_.empty() && commands_.empty()) return false;  // the idle path allocates nothing
  events.swap(events_);
  commands.swap(commands_);
  return true;
}

}  // namespace hapticloth::transport
