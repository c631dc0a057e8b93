// A live run over zenoh: the scene from the server's queryable, then the cloth and haptic
// topics collected into a Recording (the renderer draws it like a log).
#pragma once

#include <string>

#include "render/recording.hpp"

namespace hapticloth::render {

struct ZenohCollect {
  std::string endpoint = "tcp/127.0.0.1:7447";  ///< the server's listen endpoint
  std::string server = "default";               ///< key expressions hapticloth/<server>/...
  double timeout = 5.0;     ///< s, for the scene answer and for the first cloth state
  double duration = 10.0;   ///< s of wall clock to collect for (after the first cloth state)
  double idle = 2.0;        ///< s without a cloth state that ends the collection early
  double until_time = -1.0; ///< >= 0: stop at the first cloth state at or after this session time
  bool single = false;      ///< stop at the first cloth state (after until_time, if set)
};

/// Connects as a zenoh client to `endpoint` (no scouting; retried until `timeout`), asks hapticloth/<server>/scene, then
/// collects hapticloth/<server>/cloth and /haptics as `opt` says. Throws InputError when the
/// scene does not come ("no answer from ... within T s (is the server running with zenoh?)")
/// or no cloth state arrives in time, std::runtime_error when zenoh cannot open.
Recording collect_zenoh(const ZenohCollect& opt);

}  // namespace hapticloth::render
