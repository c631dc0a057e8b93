#include "haptics/loop/tactile_trace.hpp"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>

#include "tactile/spectrum.hpp"

namespace hapticloth::haptics {

namespace {
constexpr double kMinStroke = 0.25;  // s: a slide shorter than this is a touch, not a stroke
constexpr int kMaxGap = 5;           // ticks without texture a slide may have (a stick)
constexpr double kMaxWindow = 1.5;   // s analysed at most (the DFT is O(N^2))
}  // namespace

TactileTrace::TactileTrace(const cloth::Surface& surface, int fingers, int block, double rate, double tick_s,
                           long ticks)
    : surface_(surface), fingers_(fingers), block_(block), rate_(rate), tick_s_(tick_s), capacity_(ticks),
      ticks_(static_cast<size_t>(ticks * fingers)), samples_(static_cast<size_t>(ticks * fingers * block)) {}

void TactileTrace::on_tactile(const HapticReport& r, const TactileRendering& t,
                              const devices::TactileCommand& c) noexcept {
  if (static_cast<long>(kept_) >= capacity_) {
    ++lost_;
    return;
  }
  const long k = static_cast<long>(kept_++);
  for (int f = 0; f < fingers_; ++f) {
    Tick& q = ticks_[static_cast<size_t>(k * fingers_ + f)];
    const devices::TactileFrame& fr = c.finger[f];
    const TactilePlace& p = t.place(f);
    float* dst = &samples_[static_cast<size_t>((k * fingers_ + f) * block_)];
    const int n = std::min(fr.samples, block_);
    std::fill(dst, dst + block_, 0.0f);
    std::copy(fr.vibration.begin(), fr.vibration.begin() + n, dst);
    q.textured = std::any_of(dst, dst + block_, [](float x) { return x != 0.0f; });
    q.time = r.time;
    q.u = p.u;
    q.v = p.v;
    q.tip = r.finger[f].position;
  }
}

// Finger f's stroke: of its stretches of textured ticks (gaps of kMaxGap allowed) lasting
// kMinStroke or more, the one that moved furthest over the fabric; its middle 80% analysed.
bool TactileTrace::stroke(int f, TactileStroke& s) const {
  long best_a = 0, best_b = -1, a = -1, last = -1;
  double best = -1.0;
  auto consider = [&](long from, long to) {
    if (from < 0 || (to - from + 1) * tick_s_ < kMinStroke) return;
    const long n = to - from + 1;
    const Tick &p = at(from + n / 10, f), &q = at(to - n / 10, f);
    const double moved = std::hypot(q.u - p.u, q.v - p.v);
    if (moved > best) best = moved, best_a = from, best_b = to;
  };
  for (long k = 0; k < static_cast<long>(kept_); ++k) {
    if (!at(k, f).textured) continue;
    if (a < 0 || k - last > kMaxGap + 1) {
      consider(a, last);
      a = k;
    }
    last = k;
  }
  consider(a, last);
  if (best < 0.0) return false;
  const long n = best_b - best_a + 1;
  long k0 = best_a + n / 10, k1 = best_b - n / 10;
  k1 = std::min(k1, k0 + static_cast<long>(kMaxWindow / tick_s_));
  const Tick &p = at(k0, f), &q = at(k1, f);
  const double T = q.time - p.time;
  s.finger = f;
  s.start = p.time;
  s.end = q.time;
  // The speed over the fabric that sets the frequency: the median over 50 ms windows (the
  // tracker's pulls towards its anchor add short bursts of speed that a mean would count).
  std::vector<double> su, sv;
  const long w = std::max(1L, static_cast<long>(std::lround(0.05 / tick_s_)));
  for (long k = k0; k + w <= k1; k += w / 5 + 1) {
    const Tick &a = at(k, f), &b = at(k + w, f);
    su.push_back((b.u - a.u) / (b.time - a.time));
    sv.push_back((b.v - a.v) / (b.time - a.time));
  }
  auto median = [](std::vector<double>& x) {
    if (x.empty()) return 0.0;
    std::nth_element(x.begin(), x.begin() + x.size() / 2, x.end());
    return x[x.size() / 2];
  };
  s.speed_u = median(su);
  s.speed_v = median(sv);
  s.tip_speed = (q.tip - p.tip).norm() / T;
  std::vector<double> x;
  for (long k = k0; k <= k1; ++k)
    for (int i = 0; i < block_; ++i) x.push_back(samples_[static_cast<size_t>((k * fingers_ + f) * block_ + i)]);
  const std::vector<double> ps = tactile::power_spectrum(x);
  s.bin_hz = rate_ / static_cast<double>(x.size());
  size_t peak = 1;
  double ms = 0.0;
  for (size_t i = 1; i < ps.size(); ++i) {
    ms += 2.0 * ps[i];
    if (ps[i] > ps[peak]) peak = i;
  }
  s.rms = std::sqrt(ms);
  s.peak_hz = static_cast<double>(peak) * s.bin_hz;
  s.weft_hz = surface_.weft.empty() ? 0.0 : std::abs(s.speed_u) / surface_.weft.period();
  s.warp_hz = surface_.warp.empty() ? 0.0 : std::abs(s.speed_v) / surface_.warp.period();
  const bool weft = std::abs(s.weft_hz - s.peak_hz) <= std::abs(s.warp_hz - s.peak_hz);
  s.direction = weft ? "weft" : "warp";
  s.expected_hz = weft ? s.weft_hz : s.warp_hz;
  s.matches = std::abs(s.peak_hz - s.expected_hz) <= std::max(0.02 * s.expected_hz, s.bin_hz);
  s.carried = std::hypot(s.speed_u, s.speed_v) < 0.2 * s.tip_speed;
  return true;
}

std::vector<TactileStroke> TactileTrace::strokes() const {
  std::vector<TactileStroke> out;
  for (int f = 0; f < fingers_; ++f)
    if (TactileStroke s; stroke(f, s)) out.push_back(s);
  return out;
}

std::string TactileTrace::to_text() const {
  std::ostringstream os;
  os << std::fixed;
  for (const TactileStroke& s : strokes()) {
    os << "tactile          finger " << s.finger << (s.carried ? " carried the cloth " : " stroked ") << std::setprecision(2)
       << s.start << "-" << s.end << " s, " << std::setprecision(1) << std::hypot(s.speed_u, s.speed_v) * 1e3
       << " mm/s over the fabric (tip " << s.tip_speed * 1e3 << " mm/s): ";
    if (s.carried)
      os << "no weave frequency to follow";
    else
      os << "peak " << s.peak_hz << " Hz against v/lambda " << s.expected_hz << " Hz along the " << s.direction
         << " (bin " << s.bin_hz << " Hz" << (s.matches ? ": within 2% or a bin)" : ": OFF by more than 2% and a bin)");
    os << ", rms " << std::setprecision(3) << s.rms * 1e6 << " um\n";
  }
  if (lost_ > 0) os << "tactile          " << lost_ << " ticks beyond the trace's room not kept\n";
  return os.str();
}

nlohmann::json TactileTrace::to_json() const {
  nlohmann::json j = nlohmann::json::array();
  for (const TactileStroke& s : strokes())
    j.push_back({{"finger", s.finger}, {"start", s.start}, {"end", s.end}, {"speed_u_m_s", s.speed_u},
                 {"speed_v_m_s", s.speed_v}, {"tip_speed_m_s", s.tip_speed}, {"peak_hz", s.peak_hz},
                 {"bin_hz", s.bin_hz}, {"weft_hz", s.weft_hz}, {"warp_hz", s.warp_hz}, {"direction", s.direction},
                 {"expected_hz", s.expected_hz}, {"matches", s.matches}, {"carried", s.carried}, {"rms_m", s.rms}});
  return j;
}

}  // namespace hapticloth::haptics
