#include "cloth/surface.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

namespace hapticloth::cloth {

namespace {
constexpr int kWeaveSamples = 64;  // per yarn: the 10th harmonic still has 6 samples a period
constexpr double kPi = 3.14159265358979323846;
}  // namespace

SurfaceProfile::SurfaceProfile(double spacing, std::vector<double> height)
    : spacing_(spacing), height_(std::move(height)) {
  if (!(spacing_ > 0.0) || height_.empty()) throw std::invalid_argument("surface profile: no samples");
  const double mean = std::accumulate(height_.begin(), height_.end(), 0.0) / static_cast<double>(height_.size());
  for (double& h : height_) h -= mean;
}

double SurfaceProfile::at(double s) const noexcept {
  const double n = static_cast<double>(height_.size());
  double x = s / spacing_;
  x -= n * std::floor(x / n);  // in [0, n)
  const auto i = std::min(static_cast<size_t>(x), height_.size() - 1);
  const size_t j = i + 1 == height_.size() ? 0 : i + 1;
  const double t = x - static_cast<double>(i);
  return height_[i] + t * (height_[j] - height_[i]);
}

double SurfaceProfile::mean_deviation() const {
  double s = 0.0;
  for (double h : height_) s += std::abs(h);
  return height_.empty() ? 0.0 : s / static_cast<double>(height_.size());
}

const char* to_string(WeaveShape s) { return s == WeaveShape::Sine ? "sine" : "yarn"; }

SurfaceProfile weave_profile(double yarn_spacing, double amplitude, WeaveShape shape) {
  if (!(yarn_spacing > 0.0) || !(amplitude >= 0.0))
    throw std::invalid_argument("weave: yarn spacing must be > 0 and amplitude >= 0");
  std::vector<double> h(kWeaveSamples);
  for (int i = 0; i < kWeaveSamples; ++i) {
    const double phase = static_cast<double>(i) / kWeaveSamples;  // of a yarn
    // Sine: A sin(2 pi s / lambda). Yarn: crowns 2A above the cusps, A (2 |sin(pi s / lambda)| - 1).
    h[i] = shape == WeaveShape::Sine ? amplitude * std::sin(2.0 * kPi * phase)
                                     : amplitude * (2.0 * std::abs(std::sin(kPi * phase)) - 1.0);
  }
  return SurfaceProfile(yarn_spacing / kWeaveSamples, std::move(h));
}

SurfaceProfile trace_profile(const std::vector<double>& distance, const std::vector<double>& height) {
  if (distance.size() != height.size() || distance.size() < 8)
    throw std::invalid_argument("trace: needs at least 8 points of distance and height");
  double step = INFINITY;
  for (size_t i = 1; i < distance.size(); ++i) {
    const double d = distance[i] - distance[i - 1];
    if (!(d > 0.0)) throw std::invalid_argument("trace: distances must increase, point " + std::to_string(i + 1));
    step = std::min(step, d);
  }
  // One period spans the trace and one more step (the last point runs on into the first).
  const double length = distance.back() - distance.front();
  const auto n = static_cast<size_t>(std::lround(length / step)) + 1;
  if (n > 1000000) throw std::invalid_argument("trace: over a million samples at its smallest step");
  const double spacing = (length + step) / static_cast<double>(n);
  std::vector<double> h(n);
  size_t k = 0;
  for (size_t i = 0; i < n; ++i) {
    const double s = distance.front() + static_cast<double>(i) * spacing;
    while (k + 2 < distance.size() && distance[k + 1] < s) ++k;
    const double t = std::clamp((s - distance[k]) / (distance[k + 1] - distance[k]), 0.0, 1.0);
    h[i] = height[k] + t * (height[k + 1] - height[k]);
  }
  return SurfaceProfile(spacing, std::move(h));
}

double Surface::friction(double u, double v) const noexcept {
  return miu + mmd * phi_scale_ * height(u, v);
}

void Surface::normalize_friction() {
  // mean |h_weft(u) + h_warp(v)| over a period of each (up to 256 samples of each)
  auto grid = [](const SurfaceProfile& p) {
    std::vector<double> g;
    if (p.empty()) return std::vector<double>{0.0};
    const size_t n = p.samples().size(), stride = std::max<size_t>(1, n / 256);
    for (size_t i = 0; i < n; i += stride) g.push_back(p.samples()[i]);
    return g;
  };
  const std::vector<double> a = grid(weft), b = grid(warp);
  double s = 0.0;
  for (double x : a)
    for (double y : b) s += std::abs(x + y);
  const double mean_abs = s / static_cast<double>(a.size() * b.size());
  phi_scale_ = mean_abs > 0.0 ? 1.0 / mean_abs : 0.0;
}

}  // namespace hapticloth::cloth
