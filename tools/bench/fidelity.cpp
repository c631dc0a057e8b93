// hapticloth-bench fidelity: the touch against physics (BENCHMARKS.md, "Force fidelity").
//   drum: the rendered force of a frictionless fingertip pressed into a pre-tensioned drum
//     against the exact rigid-sphere-on-membrane solution at 1, 2 and 3 mm, per mesh (graded
//     discs, centre edge 0.25 mm up to the fingertip radius), and where contact began;
//   handkerchief: a free cloth pinched from either side and held 6 s: the vertical sum of the
//     rendered forces against its weight over the last second, where its centre ended, how deep
//     any cloth point got into a fingertip, and Newton's third law from the cloth's momentum;
//     across meshes, squeezes, friction and both solvers, and on both sides of 2 mu N = m g.
#include <chrono>
#include <iostream>

#include "accuracy.hpp"
#include "support/touch_scenes.hpp"

namespace hapticloth::bench {

using nlohmann::json;

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

json drum_row(double centre_edge, const std::string& solver, bool verbose) {
  test::DrumSpec spec;
  spec.centre_edge = centre_edge;
  spec.solver = solver;
  const auto t0 = std::chrono::steady_clock::now();
  const test::DrumResult r = test::press_drum(spec);
  json j = {{"centre_edge_mm", centre_edge * 1e3},
            {"solver", solver},
            {"triangles", r.triangles},
            {"onset_depth_mm", r.onset_depth * 1e3},
            {"max_penetration_mm", r.max_penetration * 1e3},
            {"sim_step_p50_us", r.report.sim_step_us.quantile(0.5)},
            {"wall_s", seconds_since(t0)}};
  for (const auto& p : r.points)
    j["points"].push_back({{"depth_mm", p.depth * 1e3},
                           {"force_n", p.force},
                           {"exact_n", p.reference},
                           {"small_slope_n", test::small_slope_force(spec.drum, p.depth)},
                           {"error", p.error()}});
  if (verbose) std::cerr << "drum " << j.dump() << "\n";
  return j;
}

json pinch_row(const test::PinchSpec& spec, bool verbose) {
  const auto t0 = std::chrono::steady_clock::now();
  const test::PinchResult r = test::pinch_handkerchief(spec);
  json j = {{"quads", spec.quads},
            {"squeeze_mm", spec.squeeze * 1e3},
            {"friction", spec.friction},
            {"solver", spec.solver},
            {"weight_n", r.weight},
            {"carried_n", r.carried},
            {"error", r.error()},
            {"centre_offset_mm", r.centre_offset * 1e3},
            {"max_penetration_mm", r.max_penetration * 1e3},
            {"third_law_n", r.third_law},
            {"sim_step_p50_us", r.report.sim_step_us.quantile(0.5)},
            {"sim_step_p99_us", r.report.sim_step_us.quantile(0.99)},
            {"wall_s", seconds_since(t0)}};
  if (verbose) std::cerr << "handkerchief " << j.dump() << "\n";
  return j;
}

}  // namespace

json fidelity(const FidelityOptions& opt) {
  json out;
  const std::vector<double> edges =
      opt.quick ? std::vector<double>{1e-3, 8e-3}
                : std::vector<double>{0.25e-3, 0.5e-3, 1e-3, 2e-3, 4e-3, 8e-3};
  for (double e : edges) out["drum"].push_back(drum_row(e, "pcg", opt.verbose));
  if (!opt.quick) out["drum"].push_back(drum_row(0.25e-3, "cholmod", opt.verbose));
  // Handkerchief: each mesh with both solvers, the squeezes and frictions spread over them.
  struct Case { int quads; double squeeze, mu; };
  const std::vector<Case> cases =
      opt.quick ? std::vector<Case>{{20, 0.002, 0.6}}
                : std::vector<Case>{{20, 0.001, 0.6}, {20, 0.004, 1.0}, {30, 0.002, 0.6},
                                    {30, 0.004, 0.8}, {40, 0.001, 1.0}, {40, 0.002, 0.6}};
  for (const Case& c : cases)
    for (const char* solver : {"cholmod", "pcg"}) {
      test::PinchSpec s;
      s.quads = c.quads;
      s.squeeze = c.squeeze;
      s.friction = c.mu;
      s.solver = solver;
      out["handkerchief"].push_back(pinch_row(s, opt.verbose));
    }
  // Both sides of 2 mu N = m g: a light squeeze with little friction lets the cloth slip out.
  for (double mu : {0.02, 0.2}) {
    test::PinchSpec s;
    s.quads = 20;
    s.squeeze = 0.0005;
    s.friction = mu;
    out["slip"].push_back(pinch_row(s, opt.verbose));
  }
  return out;
}

}  // namespace hapticloth::bench
