// Loop statistics: fixed-bin histograms (1 us bins up to 10 ms) recorded without allocation.
#pragma once

#include <array>
#include <cstdint>
#include <string>

namespace hapticloth::haptics {

class Histogram {
 public:
  void add(double us) noexcept {
    const double v = us < 0 ? 0 : us;
    const int b = v >= kBins - 1 ? kBins - 1 : static_cast<int>(v);
    ++bins_[b];
    ++n_;
    if (v > max_) max_ = v;
    sum_ += v;
  }
  std::uint64_t count() const { return n_; }
  double max() const { return max_; }
  double mean() const { return n_ ? sum_ / n_ : 0.0; }
  /// Quantile q in [0, 1], in us (bin resolution 1 us; the top bin holds everything >= 10 ms).
  double quantile(double q) const {
    if (n_ == 0) return 0.0;
    const double target = q * static_cast<double>(n_);
    std::uint64_t acc = 0;
    for (int b = 0; b < kBins; ++b) {
      acc += bins_[b];
      if (static_cast<double>(acc) >= target) return b + 0.5 > max_ ? max_ : b + 0.5;
    }
    return max_;
  }
  /// Fraction of the values at `us` or above (to the 1 us bin).
  double fraction_at_least(double us) const {
    if (n_ == 0) return 0.0;
    std::uint64_t above = 0;
    for (int b = us <= 0 ? 0 : (us >= kBins - 1 ? kBins - 1 : static_cast<int>(us)); b < kBins; ++b) above += bins_[b];
    return static_cast<double>(above) / static_cast<double>(n_);
  }
  void clear() { *this = Histogram{}; }

 private:
  static constexpr int kBins = 10000;
  std::array<std::uint64_t, kBins> bins_{};
  std::uint64_t n_ = 0;
  double max_ = 0.0, sum_ = 0.0;
};

struct LoopStats {
  Histogram period_error_us;  ///< |actual wake-up - deadline|
  Histogram compute_us;       ///< time spent in one tick
  std::uint64_t ticks = 0;
  /// Ticks that ended after the next deadline, and ticks skipped after a late start (a late
  /// wake-up of the kernel's, or the tick before overrunning).
  std::uint64_t missed_deadlines = 0;
  std::uint64_t overruns = 0;  ///< ticks whose own compute took longer than the period
};

}  // namespace hapticloth::haptics
