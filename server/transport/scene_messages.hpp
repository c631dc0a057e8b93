// The scene as clients get it: scene_info_t (the zenoh queryable's answer and the scene topic),
// encoded once, the topology message, and whether a client asked for them again.
#pragma once

#include <atomic>
#include <cstdint>
#include <vector>

#include "transport/codec.hpp"
#include "transport/options.hpp"
#include "transport/scene_info.hpp"

namespace hapticloth::transport {

class SceneMessages {
 public:
  /// Encodes scene_info_t: the scene, the rates and limits of `opt`, every topic with its key
  /// expression and LCM channel, and the topology. The start counts as a request (unless
  /// opt.hold_until_session: the session's start does).
  SceneMessages(const TransportOptions& opt, const SceneInfo& scene);

  /// Any thread: the encoded scene_info_t.
  const std::vector<std::uint8_t>& info_bytes() const { return info_; }
  /// cloth_topology_t, stamped now.
  void topology(hapticloth::cloth_topology_t& m) const { fill(scene_, m); }

  /// Any thread: a client asked for the scene (LCM scene_request_t).
  void request() { requested_.store(true); }
  /// Publisher thread: true once per request.
  bool take_request() { return requested_.exchange(false); }

 private:
  const SceneInfo& scene_;
  std::vector<std::uint8_t> info_;
  std::atomic<bool> requested_;
};

}  // namespace hapticloth::transport
