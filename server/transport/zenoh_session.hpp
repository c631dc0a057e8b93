// C++ handles over the zenoh bridge (zenoh_bridge/include/zenoh_bridge.h). Constructors throw
// std::runtime_error with zenoh's message; destructors undeclare. Destroy publishers,
// subscribers and queryables before their session.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

struct HzSession;
struct HzPublisher;
struct HzSubscriber;
struct HzQueryable;

namespace hapticloth::transport {

/// The configuration used when no file is given: peer mode, listen on `listen`, multicast and
/// gossip scouting off (nothing leaves the host unless a client connects to `listen`).
std::string default_zenoh_config(const std::string& listen);

/// A session that could not be opened: a bad or unreadable config, an endpoint in use.
struct ZenohOpenError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class ZenohSession {
 public:
  /// From a JSON5 file if `config_path` is not empty, else default_zenoh_config(listen).
  ZenohSession(const std::string& config_path, const std::string& listen);
  /// From a JSON5 configuration text.
  struct Json5 {
    std::string text;
  };
  explicit ZenohSession(const Json5& config);
  ~ZenohSession();
  ZenohSession(const ZenohSession&) = delete;
  ZenohSession& operator=(const ZenohSession&) = delete;
  const HzSession* raw() const { return s_; }

 private:
  HzSession* s_ = nullptr;
};

class ZenohPublisher {
 public:
  ZenohPublisher(const ZenohSession& s, const std::string& key);
  ~ZenohPublisher();
  ZenohPublisher(const ZenohPublisher&) = delete;
  ZenohPublisher& operator=(const ZenohPublisher&) = delete;
  /// At least one subscriber matches the key expression (kept current by zenoh).
  bool matching() const;
  /// False on error (congestion drops are not errors).
  bool put(const std::uint8_t* data, std::size_t len) const;

 private:
  HzPublisher* p_ = nullptr;
};

/// Calls `on_sample(bytes, len)` on a zenoh thread for every sample; it must not throw.
class ZenohSubscriber {
 public:
  using Handler = std::function<void(const std::uint8_t*, std::size_t)>;
  ZenohSubscriber(const ZenohSession& s, const std::string& key, Handler on_sample);
  ~ZenohSubscriber();
  ZenohSubscriber(const ZenohSubscriber&) = delete;
  ZenohSubscriber& operator=(const ZenohSubscriber&) = delete;

 private:
  static void trampoline(const std::uint8_t* data, std::size_t len, const char*, std::size_t, void* ctx);
  Handler h_;
  HzSubscriber* sub_ = nullptr;
};

/// Answers every query on `key` with the bytes `answer()` returns (on a zenoh thread); no
/// answer while it returns none.
class ZenohQueryable {
 public:
  using Answer = std::function<std::vector<std::uint8_t>()>;
  ZenohQueryable(const ZenohSession& s, const std::string& key, Answer answer);
  ~ZenohQueryable();
  ZenohQueryable(const ZenohQueryable&) = delete;
  ZenohQueryable& operator=(const ZenohQueryable&) = delete;

 private:
  Answer a_;
  HzQueryable* q_ = nullptr;
};

/// Queries `selector`; calls `on_reply(bytes, len)` on this thread for every reply until all
/// arrived or `timeout_ms` passed. Returns the number of replies; throws on error.
int zenoh_get(const ZenohSession& s, const std::string& selector, unsigned timeout_ms,
              const std::function<void(const std::uint8_t*, std::size_t)>& on_reply);

}  // namespace hapticloth::transport
