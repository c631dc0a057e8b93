// hapticloth-bench late-ticks: the touch when the kernel wakes the haptic thread late
// (docs/haptic-loop.md, "Late ticks"). The main job's scene and script (the hanging square,
// tools/scenes/touch_stroke_pinch.toml) on the stepped clock, directly coupled; in each case's
// window (press, stroke, pinch) three ticks start L late (1, 2, 5, 10 or 20 ms) at random
// moments (seeded), and every later tick with them. Per case: the energy the coupling gave
// beyond passivity (the passivity observer's deepest deficit over the run), the largest
// tick-to-tick change of a rendered force from a late tick to 50 ms after its catch-up, and
// the same with the catch-up and the controller off; beside it the largest change in the
// whole window on time.
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "accuracy.hpp"
#include "bench_common.hpp"

namespace hapticloth::bench {

namespace {

using nlohmann::json;
using haptics::Vec3;

struct Window {
  const char* name;
  double from, to;  // s of the script
};
// touch_stroke_pinch.toml: the press from 1.0 s (touch at about 1.8 s), the stroke 2.0-3.5 s,
// the pinch and lift 5.0-7.8 s.
constexpr Window kWindows[] = {{"press", 1.5, 2.0}, {"stroke", 2.0, 3.5}, {"pinch", 5.4, 7.8}};
constexpr int kLatePerRun = 3;

struct RunOutcome {
  double max_jump = 0.0;        // N, in the window
  double deficit = 0.0;         // J, the observer's deepest deficit over the run
  std::uint64_t late = 0, pc_ticks = 0;
};

// Tick indices (of the 1 kHz schedule) that come late: kLatePerRun in [from, to - 0.15 s],
// at least 80 ms apart.
std::vector<long> late_moments(unsigned seed, const Window& w, double rate) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(w.from + 0.05, w.to - 0.15);
  std::vector<double> t;
  for (int tries = 0; static_cast<int>(t.size()) < kLatePerRun && tries < 1000; ++tries) {
    const double c = u(rng);
    if (std::all_of(t.begin(), t.end(), [&](double o) { return std::abs(o - c) >= 0.08; })) t.push_back(c);
  }
  std::vector<long> ticks;
  for (double c : t) ticks.push_back(std::lround(c * rate));
  std::sort(ticks.begin(), ticks.end());
  return ticks;
}

RunOutcome run(const app::Scene& sc, const cloth::ClothModel& m, const cloth::ClothState& start,
               const devices::Trajectory& script, const Window& w, const std::vector<long>& late,
               double late_s, bool guard) {
  const RunConfig c = default_config(sc);
  MockRig rig(sc, m, start, script, c, sc.haptics.haptic_rate, sc.haptics.mapping.origin);
  haptics::Session& session = *rig.session;
  RunOutcome o;
  std::array<Vec3, haptics::kMaxFingers> prev{};
  // The jumps counted: on time, all of the window's; with late ticks, those from each late
  // tick to 50 ms after its catch-up.
  const long after = std::lround(late_s * sc.haptics.haptic_rate) + std::lround(0.05 * sc.haptics.haptic_rate);
  long k = -1, until = -1;
  session.run_stepped_late(
      w.to, 0.0,
      [&](long i) { return std::binary_search(late.begin(), late.end(), i) ? late_s : 0.0; },
      [&](haptics::HapticLoop& h, const haptics::SimWorker&) {
        if (++k == 0) h.set_time_guard(guard);
        if (std::binary_search(late.begin(), late.end(), k)) until = k + after;
        const bool counted = late.empty() ? h.last_report().time >= w.from : k <= until;
        for (int f = 0; f < h.fingers(); ++f) {
          const Vec3& F = h.last_command().force[f];
          if (counted) o.max_jump = std::max(o.max_jump, (F - prev[f]).norm());
          prev[f] = F;
        }
        o.deficit = h.passivity().stats().deepest_deficit_j;
        o.pc_ticks = h.passivity().stats().active_ticks;
        o.late = h.late_ticks();
      });
  return o;
}

}  // namespace

json late_ticks(const LateTickOptions& opt) {
  const app::Scene sc = main_scene(opt.source_dir);
  const cloth::ClothModel m = app::build_model(sc);
  const cloth::ClothState start = settle(sc, m, cloth::rest_state(m), 5e-3, sc.preroll);
  const devices::Trajectory script =
      devices::load_trajectory(opt.source_dir + "/tools/scenes/touch_stroke_pinch.toml", 2);
  const double rate = sc.haptics.haptic_rate;
  json cases = json::array();
  double worst_energy = 0.0, worst_ratio = 0.0;
  for (const Window& w : kWindows) {
    const RunOutcome on_time = run(sc, m, start, script, w, {}, 0.0, true);
    for (double late_ms : {1.0, 2.0, 5.0, 10.0, 20.0}) {
      const unsigned seed = opt.seed + static_cast<unsigned>(late_ms * 10) + 1000u * static_cast<unsigned>(&w - kWindows);
      const std::vector<long> late = late_moments(seed, w, rate);
      const RunOutcome g = run(sc, m, start, script, w, late, late_ms * 1e-3, true);
      const RunOutcome u = run(sc, m, start, script, w, late, late_ms * 1e-3, false);
      std::vector<double> at;
      for (long k : late) at.push_back(k / rate);
      // One JSON object per case (its keys: docs/programs.md).
      cases.push_back({{"name", w.name},
                       {"late_ms", late_ms},
                       {"late_at_s", at},
                       {"late_ticks", g.late},
                       {"injected_energy_j", g.deficit},
                       {"max_force_jump_n", g.max_jump},
                       {"on_time_max_force_jump_n", on_time.max_jump},
                       {"on_time_injected_energy_j", on_time.deficit},
                       {"controller_ticks", g.pc_ticks},
                       {"unguarded", {{"injected_energy_j", u.deficit}, {"max_force_jump_n", u.max_jump}}}});
      worst_energy = std::max(worst_energy, g.deficit);
      if (on_time.max_jump > 0.0) worst_ratio = std::max(worst_ratio, g.max_jump / on_time.max_jump);
      if (opt.verbose)
        std::fprintf(stderr, "late-ticks: %s, %g ms late: energy %.2e J, jump %.3f N (on time %.3f N; "
                     "unguarded %.2e J, %.3f N)\n", w.name, late_ms, g.deficit, g.max_jump,
                     on_time.max_jump, u.deficit, u.max_jump);
    }
  }
  return {{"benchmark", "late-ticks"},
          {"scene", "hanging_square"},
          {"script", "tools/scenes/touch_stroke_pinch.toml"},
          {"seed", opt.seed},
          {"late_ticks_per_case", kLatePerRun},
          {"cases", cases},
          {"worst_injected_energy_j", worst_energy},
          {"worst_jump_over_on_time", worst_ratio},
          {"criteria", {{"injected_energy_j_max", 1e-3}, {"jump_over_on_time_max", 2.0}}}};
}

}  // namespace hapticloth::bench
