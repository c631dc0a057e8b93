// One LCM provider (udpm://, memq://, file://...) with an optional receive thread.
// publish() is thread-safe. Subscribe before start(); handlers run on the receive thread and
// must not throw.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

typedef struct _lcm_t lcm_t;

namespace hapticloth::transport {

class LcmBus {
 public:
  using Handler = std::function<void(const std::uint8_t*, std::size_t)>;
  /// Throws std::runtime_error if the provider cannot be created (bad URL, unwritable log).
  explicit LcmBus(const std::string& url);
  ~LcmBus();
  LcmBus(const LcmBus&) = delete;
  LcmBus& operator=(const LcmBus&) = delete;

  /// False on error.
  bool publish(const std::string& channel, const std::uint8_t* data, std::size_t len);
  void subscribe(const std::string& channel, Handler h);
  /// Starts the receive thread (only if there are subscriptions).
  void start();
  const std::string& url() const { return url_; }

 private:
  struct Sub {
    LcmBus* bus;
    Handler h;
  };
  std::string url_;
  lcm_t* lcm_ = nullptr;
  std::vector<std::unique_ptr<Sub>> subs_;
  std::atomic<bool> stop_{false};
  std::thread rx_;
};

/// "file:///abs/path?mode=w" for a log path (made absolute).
std::string lcm_log_url(const std::string& path);

}  // namespace hapticloth::transport
