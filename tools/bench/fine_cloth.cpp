// hapticloth-bench accuracy --fine-cloth: the multirate path on a cloth too large for a 1 ms
// step (tools/scenes/hanging_square_16k.toml, 15842 triangles) against the same scene directly
// coupled at 1 ms, both on the stepped clock, with the main job's touch-stroke-pinch-lift script
// (tools/scenes/touch_stroke_pinch.toml; the hanging square's device mapping). Per run: the
// relative RMS error of the rendered force every 1 ms, and how far the global cloth is from the
// surface of the global proxy (the multirate path: the proxy its rendered force puts in the
// global cloth, bench_common.hpp, proxy_in_global_cloth) at every global step in contact.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>

#include "accuracy.hpp"
#include "bench_common.hpp"
#include "haptics/contact/geometry.hpp"
#include "mock/trajectory.hpp"

namespace hapticloth::bench {

using nlohmann::json;
using Vec3 = Eigen::Vector3d;

namespace {

struct FineRun {
  std::vector<Vec3> force;    // per finger, every 1 ms
  double max_gap = 0.0;       // m: | distance(proxy in the global cloth, cloth) - r |, in contact, per step
  long gap_checks = 0;
  double cpu = 0.0;
  cloth::IntegratorEvents events;
};

double distance_to_surface(const Vec3& p, const std::vector<Vec3>& x, const cloth::ClothModel& m) {
  double best = 1e300;
  for (const auto& e : m.elements)
    best = std::min(best, haptics::closest_point_triangle(p, x[e.v[0]], x[e.v[1]], x[e.v[2]]).dist2);
  return std::sqrt(best);
}

FineRun run(const app::Scene& sc, const cloth::ClothModel& m, const cloth::ClothState& start,
            const devices::Trajectory& script, const RunConfig& c) {
  MockRig rig(sc, m, start, script, c, 1000.0, sc.haptics.mapping.origin);
  FineRun out;
  const double r = sc.haptics.finger.radius;
  std::uint64_t steps = 0;
  const auto t0 = std::chrono::steady_clock::now();
  rig.session->run_stepped(script.duration(), c.dt, [&](const haptics::HapticLoop& h, const haptics::SimWorker& w) {
    const auto& rep = h.last_report();
    for (int f = 0; f < 2; ++f) out.force.push_back(rep.finger[f].force);
    if (w.steps() == steps) return;
    steps = w.steps();
    for (int f = 0; f < 2; ++f) {
      if (!rep.finger[f].in_contact) continue;
      // Direct coupling: the global proxy solved with the cloth; the multirate path: where its
      // rendered force puts the proxy in the global cloth.
      const Vec3 proxy = c.multirate ? proxy_in_global_cloth(rep.finger[f], w.integrator(), f)
                                     : w.integrator().proxies()[f].x;
      const double gap = std::abs(distance_to_surface(proxy, w.state().x, m) - r);
      out.max_gap = std::max(out.max_gap, gap);
      ++out.gap_checks;
    }
  });
  out.cpu = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  out.events = rig.session->sim().integrator().events();
  return out;
}

}  // namespace

json fine_cloth(const AccuracyOptions& opt) {
  const app::Scene sc = main_scene(opt.source_dir);
  app::Scene fine = app::load_scene(opt.fine_scene.empty()
                                        ? opt.source_dir + "/tools/scenes/hanging_square_16k.toml"
                                        : opt.fine_scene);
  fine.haptics = sc.haptics;  // the device, mapping and fingertip of the main job
  fine.device = sc.device;
  const auto say = progress("fine-cloth", opt.verbose);
  const cloth::ClothModel m = app::build_model(fine);
  say("settling " + std::to_string(m.num_triangles()) + " triangles (CHOLMOD, dt 20 ms)");
  const cloth::ClothState start = settle(fine, m, cloth::rest_state(m), 0.02, sc.preroll);
  const devices::Trajectory script =
      devices::load_trajectory(opt.source_dir + "/tools/scenes/touch_stroke_pinch.toml", 2);
  RunConfig direct = default_config(fine);  // the scene's own solver settings
  direct.dt = 1e-3;
  say("reference: direct coupling at 1 ms");
  const FineRun ref = run(fine, m, start, script, direct);
  double fmax = 0.0;
  for (const auto& f : ref.force) fmax = std::max(fmax, f.norm());
  json runs = json::array();
  auto row = [&](const std::string& name, const RunConfig& c, const FineRun& fr) {
    double num = 0.0, den = 0.0;
    for (size_t k = 0; k < fr.force.size() && k < ref.force.size(); ++k) {
      num += (fr.force[k] - ref.force[k]).squaredNorm();
      den += ref.force[k].squaredNorm();
    }
    runs.push_back({{"run", name},
                    {"dt_ms", c.dt * 1e3},
                    {"force_err_rel", den > 0.0 ? std::sqrt(num / den) : 0.0},
                    {"max_gap_mm", fr.max_gap * 1e3},
                    {"gap_checks", fr.gap_checks},
                    {"cpu_s_per_sim_s", fr.cpu / script.duration()},
                    {"restores", fr.events.restores},
                    {"retries", fr.events.retries},
                    {"solver_not_converged", fr.events.solver_not_converged},
                    {"contact_revisions", fr.events.contact_revisions}});
  };
  row("direct 1 ms (reference)", direct, ref);
  for (double dt : {0.01, 0.02, 0.04})
    for (auto model : {haptics::LocalModel::Response, haptics::LocalModel::Patch}) {
      RunConfig c = direct;
      c.dt = dt;
      c.multirate = true;
      c.local_model = model;
      say(describe(c));
      row(std::string("multirate ") + haptics::to_string(model), c, run(fine, m, start, script, c));
    }
  return {{"what", fine.name + " (" + std::to_string(m.num_triangles()) +
                       " triangles) with tools/scenes/touch_stroke_pinch.toml on the stepped clock; "
                       "force error: relative RMS against direct coupling at 1 ms, every 1 ms; gap: "
                       "| distance from the global proxy (direct coupling) or from the proxy the "
                       "rendered force puts in the global cloth (multirate) to the cloth - r | at "
                       "each global step in contact"},
          {"reference_max_force_n", fmax},
          {"runs", runs}};
}

}  // namespace hapticloth::bench
