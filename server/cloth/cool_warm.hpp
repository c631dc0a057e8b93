// The colour scale of strain pictures (hapticloth-render, the Foxglove /cloth channel): blue
// (compression) through light grey (0) to red (stretch), after Moreland's cool-warm map.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>

namespace hapticloth::cloth {

/// RGB in 0..255 of x in [-1, 1] (clamped); grey for a value that is not finite.
inline std::array<double, 3> cool_warm(double x) {
  static constexpr double kStops[5][3] = {
      {59, 76, 192}, {141, 176, 254}, {226, 226, 222}, {244, 154, 123}, {180, 4, 38}};
  if (!std::isfinite(x)) return {150, 150, 150};
  const double t = (std::clamp(x, -1.0, 1.0) + 1.0) * 2.0;  // 0..4
  const int i = std::min(3, static_cast<int>(t));
  const double f = t - i;
  std::array<double, 3> c;
  for (int k = 0; k < 3; ++k) c[k] = kStops[i][k] * (1 - f) + kStops[i + 1][k] * f;
  return c;
}

}  // namespace hapticloth::cloth
