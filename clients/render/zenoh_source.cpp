#include "render/zenoh_source.hpp"

#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <memory>
#include <mutex>
#include <thread>

#include "zenoh_bridge.h"

namespace hapticloth::render {

namespace {

std::string client_config(const std::string& endpoint) {
  return "{ mode: \"client\", connect: { endpoints: [\"" + endpoint +
         "\"] }, scouting: { multicast: { enabled: false }, gossip: { enabled: false } } }";
}

std::string seconds(double s) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g s", s);
  return buf;
}

[[noreturn]] void fail(const std::string& what) {
  char buf[512];
  hz_last_error(buf, sizeof buf);
  throw std::runtime_error("zenoh: " + what + ": " + buf);
}

// What the subscriber callbacks fill, under the mutex.
struct Shared {
  const ZenohCollect* opt = nullptr;
  std::mutex mu;
  std::condition_variable cv;
  Recording rec;
  std::size_t frames = 0;
  bool frames_done = false;  // no more cloth states wanted
  bool closed = false;       // nothing more wanted
};

void on_sample(const std::uint8_t* data, std::size_t len, const char*, std::size_t, void* ctx) {
  Shared& s = *static_cast<Shared*>(ctx);
  std::lock_guard<std::mutex> lock(s.mu);
  if (s.closed) return;
  const std::size_t frames_before = s.rec.frames.size(), ticks_before = s.rec.haptics.size();
  if (!add_message(s.rec, data, len)) return;
  if (s.rec.frames.size() == frames_before) {
    if (s.rec.haptics.size() != ticks_before) s.cv.notify_all();
    return;
  }
  // A cloth state. For a single picture at a time, the earlier ones are not needed.
  const double t = s.rec.frames.back().time, until = s.opt->until_time;
  if (s.frames_done || (s.opt->single && until >= 0.0 && t < until)) {
    s.rec.frames.pop_back();
    return;
  }
  ++s.frames;
  if (s.opt->single || (until >= 0.0 && t >= until)) s.frames_done = true;
  s.cv.notify_all();
}

void on_scene(const std::uint8_t* data, std::size_t len, const char*, std::size_t, void* ctx) {
  auto* probe = static_cast<Recording*>(ctx);
  if (!probe->has_topology) add_message(*probe, data, len);
}

}  // namespace

Recording collect_zenoh(const ZenohCollect& opt) {
  using namespace std::chrono;
  // The server may still be starting: retry the connection until the timeout.
  const auto give_up = steady_clock::now() + duration<double>(opt.timeout);
  std::unique_ptr<HzSession, void (*)(HzSession*)> session(nullptr, hz_close);
  for (;;) {
    session.reset(hz_open_json5(client_config(opt.endpoint).c_str()));
    if (session) break;
    if (steady_clock::now() >= give_up) fail("connect to " + opt.endpoint + " within " + seconds(opt.timeout));
    std::this_thread::sleep_for(milliseconds(200));
  }
  const std::string prefix = "hapticloth/" + opt.server + "/";

  Shared s;
  s.opt = &opt;
  {
    // Subscribe first, then ask for the scene: no state is missed between the two.
    std::unique_ptr<HzSubscriber, void (*)(HzSubscriber*)> cloth(
        hz_declare_subscriber(session.get(), (prefix + "cloth").c_str(), on_sample, &s), hz_undeclare_subscriber);
    if (!cloth) fail("subscribe " + prefix + "cloth");
    std::unique_ptr<HzSubscriber, void (*)(HzSubscriber*)> haptics(
        hz_declare_subscriber(session.get(), (prefix + "haptics").c_str(), on_sample, &s), hz_undeclare_subscriber);
    if (!haptics) fail("subscribe " + prefix + "haptics");

    Recording probe;
    const auto timeout_ms = static_cast<std::uint64_t>(opt.timeout * 1000.0);
    if (hz_get(session.get(), (prefix + "scene").c_str(), timeout_ms, on_scene, &probe) < 0)
      fail("get " + prefix + "scene");
    if (!probe.has_topology)
      throw InputError("no answer from " + prefix + "scene at " + opt.endpoint + " within " + seconds(opt.timeout) +
                       " (is the server running with zenoh, named " + opt.server + "?)");

    std::unique_lock<std::mutex> lock(s.mu);
    s.rec.scene = probe.scene;
    s.rec.has_topology = true;
    if (!s.cv.wait_for(lock, duration<double>(opt.timeout), [&] { return s.frames > 0; }))
      throw InputError("no cloth state on " + prefix + "cloth within " + seconds(opt.timeout));
    const auto end = steady_clock::now() + duration<double>(opt.duration);
    while (!s.frames_done && steady_clock::now() < end) {
      const std::size_t seen = s.frames;
      s.cv.wait_for(lock, duration<double>(opt.idle), [&] { return s.frames_done || s.frames != seen; });
      if (s.frames == seen && !s.frames_done) break;  // the stream stopped (the server finished)
    }
    s.frames_done = true;
    // Haptic samples come in batches: wait briefly for those up to the last cloth state.
    const double last = s.rec.frames.back().time;
    s.cv.wait_for(lock, milliseconds(250), [&] { return !s.rec.haptics.empty() && s.rec.haptics.back().time >= last; });
    s.closed = true;
  }  // undeclared: no callback runs any more
  finish(s.rec);
  return std::move(s.rec);
}

}  // namespace hapticloth::render
