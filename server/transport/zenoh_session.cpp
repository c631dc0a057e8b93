#include "transport/zenoh_session.hpp"
#include "log/input_file.hpp"

#include <stdexcept>

#include "zenoh_bridge.h"

namespace hapticloth::transport {

namespace {
// zenoh's message without the Rust source locations it appends (" at /root/.cargo/.../tcp.rs:61."):
// they say where in zenoh, not what the user gave.
std::string without_source_paths(std::string m) {
  for (std::size_t at; (at = m.find(" at /")) != std::string::npos;) {
    const std::size_t rs = m.find(".rs:", at);
    if (rs == std::string::npos) break;
    std::size_t end = m.find_first_not_of("0123456789", rs + 4);
    if (end != std::string::npos && m[end] == '.') ++end;
    m.erase(at, (end == std::string::npos ? m.size() : end) - at);
  }
  while (!m.empty() && (m.back() == '\n' || m.back() == ' ')) m.pop_back();
  return m;
}

[[noreturn]] void fail(const std::string& what) {
  char buf[1024];
  hz_last_error(buf, sizeof buf);
  throw ZenohOpenError("zenoh: " + what + ": " + without_source_paths(buf));
}

void answer_query(const HzQuery* q, const char*, std::size_t, void* ctx) {
  try {
    const std::vector<std::uint8_t> bytes = (*static_cast<ZenohQueryable::Answer*>(ctx))();
    if (!bytes.empty()) hz_query_reply(q, bytes.data(), bytes.size());  // empty: no answer (yet)
  } catch (...) {
    // A failed answer leaves the query without a reply; the client times out.
  }
}
}  // namespace

std::string default_zenoh_config(const std::string& listen) {
  return "{\n"
         "  mode: \"peer\",\n"
         "  listen: { endpoints: [\"" + listen + "\"] },\n"
         "  scouting: { multicast: { enabled: false }, gossip: { enabled: false } },\n"
         "}\n";
}

ZenohSession::ZenohSession(const std::string& config_path, const std::string& listen) {
  if (!config_path.empty()) {
    if (std::string e = devices::check_input_file(config_path, devices::kMaxConfigBytes); !e.empty())
      throw ZenohOpenError("zenoh config " + e);
    s_ = hz_open_file(config_path.c_str());
    if (!s_) fail("open with " + config_path);
  } else {
    s_ = hz_open_json5(default_zenoh_config(listen).c_str());
    if (!s_) fail("open listening on " + listen);
  }
}
ZenohSession::ZenohSession(const Json5& config) : s_(hz_open_json5(config.text.c_str())) {
  if (!s_) fail("open");
}
ZenohSession::~ZenohSession() { hz_close(s_); }

ZenohPublisher::ZenohPublisher(const ZenohSession& s, const std::string& key)
    : p_(hz_declare_publisher(s.raw(), key.c_str())) {
  if (!p_) fail("publisher " + key);
}
ZenohPublisher::~ZenohPublisher() { hz_undeclare_publisher(p_); }
bool ZenohPublisher::matching() const { return hz_publisher_matching(p_) != 0; }
bool ZenohPublisher::put(const std::uint8_t* data, std::size_t len) const {
  return hz_put(p_, data, len) == 0;
}

ZenohSubscriber::ZenohSubscriber(const ZenohSession& s, const std::string& key, Handler h)
    : h_(std::move(h)) {
  sub_ = hz_declare_subscriber(s.raw(), key.c_str(), &ZenohSubscriber::trampoline, this);
  if (!sub_) fail("subscriber " + key);
}
ZenohSubscriber::~ZenohSubscriber() { hz_undeclare_subscriber(sub_); }
void ZenohSubscriber::trampoline(const std::uint8_t* data, std::size_t len, const char*, std::size_t,
                                 void* ctx) {
  try {
    static_cast<ZenohSubscriber*>(ctx)->h_(data, len);
  } catch (...) {
    // Handlers must not throw; a sample that made one throw is dropped.
  }
}

ZenohQueryable::ZenohQueryable(const ZenohSession& s, const std::string& key, Answer a)
    : a_(std::move(a)) {
  q_ = hz_declare_queryable(s.raw(), key.c_str(), &answer_query, &a_);
  if (!q_) fail("queryable " + key);
}
ZenohQueryable::~ZenohQueryable() { hz_undeclare_queryable(q_); }

int zenoh_get(const ZenohSession& s, const std::string& selector, unsigned timeout_ms,
              const std::function<void(const std::uint8_t*, std::size_t)>& on_reply) {
  using F = std::function<void(const std::uint8_t*, std::size_t)>;
  const int n = hz_get(
      s.raw(), selector.c_str(), timeout_ms,
      [](const std::uint8_t* d, std::size_t len, const char*, std::size_t, void* ctx) {
        try {
          (*static_cast<const F*>(ctx))(d, len);
        } catch (...) {
        }
      },
      const_cast<F*>(&on_reply));
  if (n < 0) fail("get " + selector);
  return n;
}

}  // namespace hapticloth::transport
