// Between the server's structures and the LCM messages of proto/ (generated types in the
// hapticloth namespace). Runs on the Hub's publisher thread and the transports' receive
// threads, never on the real-time path.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "haptics/loop/stats.hpp"
#include "hal/device.hpp"
#include "remote/command_sink.hpp"
#include "transport/scene_info.hpp"

#include "hapticloth/cloth_state_t.hpp"
#include "hapticloth/cloth_topology_t.hpp"
#include "hapticloth/event_t.hpp"
#include "hapticloth/haptic_state_t.hpp"
#include "hapticloth/loop_stats_t.hpp"
#include "hapticloth/scene_info_t.hpp"
#include "hapticloth/tactile_state_t.hpp"
#include "hapticloth/scene_request_t.hpp"
#include "hapticloth/trajectory_cmd_t.hpp"

namespace hapticloth::transport {

/// us since the Unix epoch.
std::int64_t wall_utime();

/// One haptic tick as the Hub keeps it (fixed size: copied on the real-time path).
struct HapticSample {
  double time = 0.0;
  std::uint64_t tick = 0;
  std::int32_t flags = 0;
  std::array<std::array<float, 3>, devices::kMaxFingers> device{}, position{}, proxy{}, force{}, command{};
  std::array<bool, devices::kMaxFingers> contact{}, slipping{};
};

/// One tick of the tactile output as the haptic loop hands it to the publisher.
struct TactileSample {
  double time = 0.0;
  std::uint64_t tick = 0;
  devices::TactileCommand out;  ///< after the safety gate (flags: its tactile flags)
  std::array<float, devices::kMaxFingers> u{}, v{}, normal_force{};
  std::array<bool, devices::kMaxFingers> touching{};
};

/// What a tactile_state_t says of the display, fixed for a session.
struct TactileLayout {
  int samples = 0, rows = 0, cols = 0, sample_rate = 0;
  float pin_pitch = 0.0f;
  float weft_period = 0.0f, warp_period = 0.0f;  ///< m, the fabric's surface (0: none)
};

/// Loop statistics reduced to what loop_stats_t carries (cheap to compute on the haptic thread:
/// the quantile scans stop at the first bins that reach them).
struct LoopSummary {
  std::uint64_t ticks = 0, missed = 0;
  float period_p50 = 0, period_p99 = 0, period_p999 = 0, period_max = 0;
  float compute_p50 = 0, compute_p99 = 0, compute_p999 = 0, compute_max = 0;
};
LoopSummary summarize(const haptics::LoopStats& s) noexcept;

void fill(const SceneInfo& info, hapticloth::cloth_topology_t& m);
void fill(const LoopSummary& s, hapticloth::loop_stats_t& m);
/// `samples[0..n)`, `fingers` per sample.
void fill(const HapticSample* samples, int n, int fingers, hapticloth::haptic_state_t& m);
/// `samples[0..n)`, `fingers` per sample, of a display laid out as `layout`.
void fill(const TactileSample* samples, int n, int fingers, const TactileLayout& layout,
          hapticloth::tactile_state_t& m);

/// A trajectory command in the device frame. Returns "" or why it cannot be converted.
std::string to_device_command(const hapticloth::trajectory_cmd_t& m, const SceneInfo& info,
                              devices::TrajectoryCommand& out);

template <class M>
void encode(const M& m, std::vector<std::uint8_t>& buf) {
  const int n = m.getEncodedSize();
  buf.resize(static_cast<std::size_t>(n));
  m.encode(buf.data(), 0, n);
}
/// False if the bytes are not a valid M.
template <class M>
bool decode(const std::uint8_t* data, std::size_t len, M& m) {
  return m.decode(data, 0, static_cast<int>(len)) >= 0;
}

}  // namespace hapticloth::transport
