// The fabric's surface (server/cloth/surface): weave and trace profiles, their periodic
// interpolation, KES-FB4's mean deviations, and the friction pattern's mean and deviation.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <vector>

#include "cloth/surface.hpp"

using namespace hapticloth::cloth;

namespace {
constexpr double kPi = 3.14159265358979323846;
}

// A sine weave: A sin(2 pi s / lambda), periodic, zero mean; its mean deviation (SMD) 2A / pi.
TEST(Surface, SineWeaveIsPeriodicWithItsMeanDeviation) {
  const double lambda = 0.5e-3, a = 20e-6;
  const SurfaceProfile p = weave_profile(lambda, a, WeaveShape::Sine);
  EXPECT_DOUBLE_EQ(p.period(), lambda);
  for (const double s : {0.0, 0.1e-3, 0.125e-3, 0.37e-3})
    for (const int n : {-3, 0, 1, 40}) EXPECT_NEAR(p.at(s + n * lambda), a * std::sin(2 * kPi * s / lambda), 0.002 * a);
  EXPECT_NEAR(p.mean_deviation(), 2 * a / kPi, 1e-3 * a);
}

// A yarn weave: crowns 2A above the cusps between yarns, zero mean.
TEST(Surface, YarnWeaveHasCrownsAndCusps) {
  const double lambda = 0.8e-3, a = 30e-6;
  const SurfaceProfile p = weave_profile(lambda, a, WeaveShape::Yarn);
  const double crown = p.at(lambda / 2), cusp = p.at(0.0);
  EXPECT_NEAR(crown - cusp, 2 * a, 1e-9);
  double mean = 0.0;
  for (double h : p.samples()) mean += h;
  EXPECT_NEAR(mean, 0.0, 1e-15);
}

// A trace with uneven steps is resampled at its smallest one and taken as one period: its
// values come back between the points, its mean removed.
TEST(Surface, TraceIsResampledAsOnePeriod) {
  std::vector<double> d, h;
  double x = 0.0;
  for (int i = 0; i < 40; ++i) {
    d.push_back(x);
    h.push_back(1e-6 * (i % 5) + 3e-6);
    x += i % 2 ? 10e-6 : 20e-6;
  }
  const SurfaceProfile p = trace_profile(d, h);
  EXPECT_NEAR(p.spacing(), 10e-6, 0.1e-6);
  EXPECT_NEAR(p.period(), d.back() - d.front() + p.spacing(), 1e-12);
  EXPECT_NEAR(p.at(d[7]) - p.at(d[3]), h[7] - h[3], 0.05e-6);
  EXPECT_THROW(trace_profile({0, 1, 2}, {0, 0, 0}), std::invalid_argument);
  std::vector<double> back = d;
  back[5] = back[4];
  EXPECT_THROW(trace_profile(back, h), std::invalid_argument);
}

// mu(u, v) = MIU + MMD phi: over a period of each direction its mean is MIU and its mean
// deviation MMD, as KES-FB4 reports them.
TEST(Surface, FrictionHasTheMeasuredMeanAndDeviation) {
  Surface s;
  s.weft = weave_profile(0.5e-3, 20e-6, WeaveShape::Yarn);
  s.warp = weave_profile(0.7e-3, 12e-6, WeaveShape::Sine);
  s.miu = 0.25;
  s.mmd = 0.02;
  s.normalize_friction();
  double mean = 0.0, dev = 0.0;
  const int n = 350;  // 0.5 x 0.7 mm: 7 x 5 periods, 1 um steps
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) mean += s.friction(i * 1e-5, j * 1e-5);
  mean /= n * n;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) dev += std::abs(s.friction(i * 1e-5, j * 1e-5) - mean);
  dev /= n * n;
  EXPECT_NEAR(mean, 0.25, 1e-4);
  EXPECT_NEAR(dev, 0.02, 0.02 * 0.02);
}
