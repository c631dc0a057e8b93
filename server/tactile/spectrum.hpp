// The power spectrum of a short signal, for the run's tactile summary, the tactile tests and
// `hapticloth-bench tactile` (a plain DFT: their signals are a few thousand samples). Off the
// real-time path.
#pragma once

#include <cmath>
#include <complex>
#include <vector>

namespace hapticloth::tactile {

/// |X_k|^2 / N^2 of the mean-removed signal, bins 0..N/2 (Parseval: their sum over both halves
/// is the signal's mean square).
inline std::vector<double> power_spectrum(const std::vector<double>& x) {
  const size_t n = x.size();
  double mean = 0.0;
  for (double v : x) mean += v;
  mean /= static_cast<double>(n);
  std::vector<double> p(n / 2 + 1);
  for (size_t k = 0; k < p.size(); ++k) {
    const std::complex<double> w =
        std::polar(1.0, -2.0 * 3.14159265358979323846 * static_cast<double>(k) / static_cast<double>(n));
    std::complex<double> acc = 0.0, wk = 1.0;
    for (size_t i = 0; i < n; ++i, wk *= w) acc += (x[i] - mean) * wk;
    p[k] = std::norm(acc) / (static_cast<double>(n) * static_cast<double>(n));
  }
  return p;
}

/// A spectrum's energy (bins df Hz apart, DC left out) in each third-octave band from 20 to
/// 400 Hz: 14 bands, centres 20 x 2^(i/3) Hz.
inline std::vector<double> third_octave_bands(const std::vector<double>& p, double df) {
  std::vector<double> e;
  for (double fc = 20.0; fc <= 400.0 * 1.0001; fc *= std::pow(2.0, 1.0 / 3.0)) {
    const double lo = fc * std::pow(2.0, -1.0 / 6.0), hi = fc * std::pow(2.0, 1.0 / 6.0);
    double sum = 0.0;
    for (size_t k = 1; k < p.size(); ++k)
      if (static_cast<double>(k) * df >= lo && static_cast<double>(k) * df < hi) sum += p[k];
    e.push_back(sum);
  }
  return e;
}

}  // namespace hapticloth::tactile
