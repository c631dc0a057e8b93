// What the session's loops hand the Hub's publisher thread: the newest cloth frame (at most
// cloth_rate a second) and the newest loop statistics through triple buffers, every haptic
// sample and (with a tactile display) every tick's tactile output through rings, and counts of the faults the haptic loop flagged. The loop side copies
// into storage allocated here: no lock, no allocation.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "hal/rt_handoff.hpp"
#include "haptics/observer.hpp"
#include "transport/codec.hpp"

namespace hapticloth::transport {

class LoopMailboxes {
 public:
  /// Cloth positions as published (float, the message's precision), with the refined children
  /// under the fingertips as the simulation last gathered them (haptics::RefinedRegions).
  struct ClothFrame {
    ClothFrame() { reserve_refined(); }
    /// Copies keep the reserve (TripleBuffer copies its first frame into every slot).
    ClothFrame(const ClothFrame& o)
        : time(o.time), step(o.step), x(o.x), refined_x(o.refined_x), refined_triangles(o.refined_triangles),
          refined_uv(o.refined_uv), refined_region(o.refined_region) {
      reserve_refined();
    }
    ClothFrame& operator=(const ClothFrame&) = default;
    /// Room for two children of the finest grading (docs/contact.md: up to 500 vertices each).
    void reserve_refined() {
      refined_x.reserve(1024);
      refined_triangles.reserve(2048);
      refined_uv.reserve(2048);
      refined_region.reserve(128);
    }
    double time = -1.0;
    std::uint64_t step = 0;
    std::vector<std::array<float, 3>> x;
    std::vector<std::array<float, 3>> refined_x;
    std::vector<std::array<std::int32_t, 3>> refined_triangles;
    std::vector<std::array<std::array<float, 2>, 3>> refined_uv;
    std::vector<std::int32_t> refined_region;
  };
  static constexpr std::size_t kSamples = 4096;  ///< haptic samples the ring holds (4 s at 1 kHz)
  static constexpr std::size_t kTactileSamples = 1024;  ///< tactile ticks the ring holds (1 s at 1 kHz)

  /// Set-up: frames of `vertices` vertices, samples of `device.fingers` fingers; room for the
  /// tactile output only if the device declares a display, whose messages name the fabric's
  /// surface periods (m; 0: none).
  LoopMailboxes(std::size_t vertices, const devices::DeviceInfo& device, double cloth_rate, double weft_period = 0.0,
                double warp_period = 0.0);

  // The loops' side (one writer each: the simulation thread, the haptic thread).
  void put_cloth(const haptics::ClothSnapshot& s) noexcept;
  /// The refined children the next cloth frames carry (simulation thread, as put_cloth). Their
  /// storage is reserved for typical children and grows, off the haptic thread, for larger ones.
  void put_refined(const haptics::RefinedRegions& r) noexcept;
  void put_tick(const haptics::HapticReport& r, const devices::DeviceState& state,
                const devices::DeviceCommand& cmd) noexcept;
  void put_stats(const haptics::LoopStats& s) noexcept;
  void put_tactile(const haptics::HapticReport& r, const haptics::TactileRendering& t,
                   const devices::TactileCommand& out) noexcept;

  // The publisher's side.
  /// The newest cloth frame if one came since the last call, else nullptr.
  const ClothFrame* take_cloth();
  /// The newest loop statistics if new, else nullptr.
  const LoopSummary* take_stats();
  /// Appends the samples waiting, oldest first, up to `out`'s capacity (so never allocates
  /// once it is reserved).
  void take_samples(std::vector<HapticSample>& out);
  /// The tactile ticks waiting, as take_samples.
  void take_tactile(std::vector<TactileSample>& out);
  const TactileLayout& tactile_layout() const { return layout_; }
  bool has_tactile() const { return layout_.samples > 0 || layout_.rows > 0; }

  int fingers() const { return fingers_; }
  /// Any thread.
  std::uint64_t samples_dropped() const { return dropped_.load(); }
  std::uint64_t tactile_dropped() const { return tactile_dropped_.load(); }
  std::uint64_t watchdog_trips() const { return watchdog_trips_.load(); }
  std::uint64_t nan_forces() const { return nan_forces_.load(); }

 private:
  const int fingers_;
  const double cloth_period_;
  devices::TripleBuffer<ClothFrame> cloth_;
  double next_cloth_time_ = -1.0;  // simulation thread only
  ClothFrame refined_;             // simulation thread only: the refined fields the frames copy
  devices::TripleBuffer<LoopSummary> stats_;
  devices::SpscRing<HapticSample> samples_;
  TactileLayout layout_;
  devices::SpscRing<TactileSample> tactile_;
  // The gate starts stale (no device sample yet), and counts a trip on each fresh -> stale
  // transition; so does this (the summary's stale events and the watchdog events agree).
  bool was_stale_ = true;  // haptic thread only
  std::atomic<std::uint64_t> dropped_{0}, watchdog_trips_{0}, nan_forces_{0}, tactile_dropped_{0};
};

}  // namespace hapticloth::transport
