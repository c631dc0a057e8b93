// hapticloth-bench fidelity: the touch against physics (BENCHMARKS.md, "Force fidelity").
//   drum: the rendered force of a frictionless fingertip pressed into a pre-tensioned drum
//     against the exact rigid-sphere-on-membrane solution at 1, 2 and 3 mm, per mesh (graded
//     discs, centre edge 0.25 mm up to the fingertip radius), and where contact began;
//   handkerchief: a free cloth pinched from either side and held 6 s: the vertical sum of the
//     rendered forces against its weight over the last second, where its centre ended, how deep
//     any cloth point got into a fingertip, and Newton's third law from the cloth's momentum;
//     across meshes, squeezes, friction and both solvers, and on both sides of 2 mu N = m g;
//   multirate: the drum (1 mm mesh) and the handkerchief (20 quads) with the global step at
//     10, 20 and 40 ms, through each local model (response, patch);
//   --square-press: instead, the hanging square of the main job pressed at its middle and near
//     its pinned edge, per mesh with refinement off and on, against the finest mesh given.
#include <chrono>
#include <iostream>

#include "accuracy.hpp"
#include "bench_common.hpp"
#include "app/scene_file.hpp"
#include "support/touch_scenes.hpp"

namespace hapticloth::bench {

using nlohmann::json;

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

json drum_row(double centre_edge, const std::string& solver, bool verbose, double global_dt = 1e-3,
              haptics::LocalModel model = haptics::LocalModel::Response) {
  test::DrumSpec spec;
  spec.centre_edge = centre_edge;
  spec.solver = solver;
  spec.global_dt = global_dt;
  spec.model = model;
  const auto t0 = std::chrono::steady_clock::now();
  const test::DrumResult r = test::press_drum(spec);
  json j = {{"centre_edge_mm", centre_edge * 1e3},
            {"solver", solver},
            {"global_dt_ms", global_dt * 1e3},
            {"local_model", global_dt > 1e-3 ? haptics::to_string(model) : "direct"},
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
            {"global_dt_ms", spec.global_dt * 1e3},
            {"local_model", spec.global_dt > 1e-3 ? haptics::to_string(spec.model) : "direct"},
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

// The hanging square pressed from the front at its middle and 3 cm below its pinned edge, on
// each mesh with refinement off and on, and on the last (finest) mesh without: each force at 1,
// 2, 3 and 5 mm of proxy depth against the finest mesh's (a discretisation reference: the same
// scene, the same press, only finer).
json square_press(const std::vector<int>& quads, bool verbose) {
  json rows = json::array();
  struct Where { const char* name; double z; };
  for (const Where w : {Where{"middle", -0.25}, Where{"3 cm below the pins", -0.03}}) {
    test::SquarePressSpec ref_spec;
    ref_spec.quads = quads.back();
    ref_spec.z = w.z;
    const auto t0 = std::chrono::steady_clock::now();
    const test::SquarePressResult ref = test::press_hanging_square(ref_spec);
    auto row = [&](const test::SquarePressSpec& spec, const test::SquarePressResult& r, double seconds) {
      json j = {{"at", w.name}, {"quads", spec.quads}, {"triangles", r.triangles},
                {"refine", spec.refine == haptics::Refine::On ? "on" : "off"},
                {"onset_mm", r.onset_depth * 1e3}, {"seconds", seconds}};
      for (size_t i = 0; i < r.points.size(); ++i) {
        const double f = r.points[i].second, f_ref = ref.points[i].second;
        j["points"].push_back({{"depth_mm", r.points[i].first * 1e3}, {"force_n", f},
                               {"reference_n", f_ref}, {"error", f_ref > 0.0 ? f / f_ref - 1.0 : 0.0}});
      }
      if (verbose) std::cerr << j.dump() << "\n";
      return j;
    };
    rows.push_back(row(ref_spec, ref, seconds_since(t0)));
    for (size_t m = 0; m + 1 < quads.size(); ++m)
      for (auto refine : {haptics::Refine::Off, haptics::Refine::On}) {
        test::SquarePressSpec spec = ref_spec;
        spec.quads = quads[m];
        spec.refine = refine;
        const auto t1 = std::chrono::steady_clock::now();
        const test::SquarePressResult r = test::press_hanging_square(spec);
        rows.push_back(row(spec, r, seconds_since(t1)));
      }
  }
  return rows;
}

json fidelity(const FidelityOptions& opt) {
  json out;
  if (!opt.square_press.empty()) {
    out["square_press"] = square_press(opt.square_press, opt.verbose);
    return out;
  }
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
  // The multirate path: each local model at long global steps.
  for (double dt : opt.quick ? std::vector<double>{0.02} : std::vector<double>{0.01, 0.02, 0.04})
    for (auto model : {haptics::LocalModel::Response, haptics::LocalModel::Patch}) {
      out["multirate"]["drum"].push_back(drum_row(1e-3, "pcg", opt.verbose, dt, model));
      test::PinchSpec s;
      s.quads = 20;
      s.solver = "pcg";
      s.global_dt = dt;
      s.model = model;
      out["multirate"]["handkerchief"].push_back(pinch_row(s, opt.verbose));
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

// The median integrator time of the steps solved 1, 2, 3 and 4 or more times (0 where none).
json by_solves_p50(const std::array<haptics::Histogram, 4>& h) {
  json out = json::array();
  for (const auto& x : h) out.push_back(x.count() ? x.quantile(0.5) : 0.0);
  return out;
}

namespace {

// Where the two fingertips pinch: a point of the cloth and the direction across it.
struct PinchSite {
  Eigen::Vector3d at, across;
};

// The middle of the start state's extent, along z (the scenes' cloths start level), offset a
// little so that the fingertips' centres are over no vertex or edge.
PinchSite middle_of_extent(const cloth::ClothModel& model) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
  for (const auto& p : model.rest_positions) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  return {0.5 * (lo + hi) + Eigen::Vector3d(0.0011, 0.0007, 0.0), Eigen::Vector3d::UnitZ()};
}

// The vertex of `s` nearest its centroid, across the cloth there (the area-weighted normal of
// the triangles around it), offset in its tangent plane as middle_of_extent's point is.
PinchSite middle_of_cloth(const cloth::ClothModel& model, const cloth::ClothState& s) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const auto& p : s.x) c += p;
  c /= static_cast<double>(s.x.size());
  int mid = 0;
  for (int i = 0; i < static_cast<int>(s.x.size()); ++i)
    if ((s.x[i] - c).squaredNorm() < (s.x[mid] - c).squaredNorm()) mid = i;
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  for (const auto& e : model.elements)
    if (e.v[0] == mid || e.v[1] == mid || e.v[2] == mid)
      n += (s.x[e.v[1]] - s.x[e.v[0]]).cross(s.x[e.v[2]] - s.x[e.v[0]]);
  n.normalize();
  const Eigen::Vector3d t1 = n.unitOrthogonal(), t2 = n.cross(t1);
  return {s.x[mid] + 0.0011 * t1 + 0.0007 * t2, n};
}

// Pinch from either side, 2 mm squeeze each, and hold.
devices::Trajectory pinch_trajectory(const PinchSite& site, double r, double seconds) {
  const double sq = 0.002;
  devices::Trajectory tr(2);
  for (int f = 0; f < 2; ++f) {
    const double side = f == 0 ? 1.0 : -1.0;
    tr.add(f, 0.0, site.at + side * r * site.across);
    tr.add(f, 0.05, site.at + side * (r - sq) * site.across);
    tr.add(f, seconds, site.at + side * (r - sq) * site.across);
  }
  return tr;
}

// Where a pinch's steps' time goes, step by step.
struct PinchSteps {
  long both = 0, ticks = 0;
  // The solver's iterations (summed over the re-solves) and the integrator's share of the step
  // (the rest is the contact's sampling and FCL).
  haptics::Histogram iterations, integrator_us;
  // The kept matrix (IntegratorConfig::matrix_refresh): elements formed anew, steps that formed
  // the matrix whole, and the rows the solver reloaded where it did not.
  haptics::Histogram rows_reloaded;
  long refreshed = 0, formed_whole = 0;
  std::uint64_t steps = 0, revisions = 0;
  // Steps by how many solves they took (1, 2, 3, 4 or more), in the squeeze (the first 0.1 s)
  // and in the hold after it: the step's tail comes from the steps solved more than once.
  std::array<std::array<long, 4>, 2> by_solves{};
  std::array<haptics::Histogram, 4> integrator_us_by_solves;
  // The same in the squeeze and in the hold: the squeeze's steps, where the contact forms and
  // the fingertips stop, take the most iterations.
  std::array<haptics::Histogram, 2> integrator_us_by_phase, iterations_by_phase;

  void record(const haptics::HapticLoop& h, const haptics::SimWorker& w) {
    ++ticks;
    both += h.last_report().finger[0].in_contact && h.last_report().finger[1].in_contact;
    if (w.steps() == steps) return;
    steps = w.steps();
    const cloth::StepTiming& t = w.integrator().last_timing();
    iterations.add(t.iterations);
    integrator_us.add(1e3 * t.total_ms);
    refreshed += t.refreshed_elements;
    formed_whole += t.whole_assemblies > 0;
    if (t.changed_rows >= 0) rows_reloaded.add(t.changed_rows);
    const std::uint64_t rev = w.integrator().events().contact_revisions;
    const auto solved = std::min<std::uint64_t>(rev - revisions, 3);
    by_solves[ticks > 100][solved]++;
    integrator_us_by_solves[solved].add(1e3 * t.total_ms);
    integrator_us_by_phase[ticks > 100].add(1e3 * t.total_ms);
    iterations_by_phase[ticks > 100].add(t.iterations);
    revisions = rev;
  }

  json phase(int i) const {
    return json{{"p50", integrator_us_by_phase[i].quantile(0.5)}, {"p99", integrator_us_by_phase[i].quantile(0.99)},
                {"iterations", iterations_by_phase[i].mean()}};
  }

  json kept_matrix(double matrix_refresh) const {
    const double n = static_cast<double>(std::max<std::uint64_t>(1, steps));
    return {{"matrix_refresh", matrix_refresh},
            {"elements_formed_per_step", static_cast<double>(refreshed) / n},
            {"steps_formed_whole", static_cast<double>(formed_whole) / n},
            {"rows_reloaded_p50", rows_reloaded.count() ? rows_reloaded.quantile(0.5) : 0.0},
            {"rows_reloaded_p99", rows_reloaded.count() ? rows_reloaded.quantile(0.99) : 0.0}};
  }
};

}  // namespace

json pinch_step(const app::Scene& scene, double seconds, double settle_s) {
  const cloth::ClothModel model = app::build_model(scene);
  haptics::SessionConfig sc = scene.haptics;
  sc.rendering = haptics::Rendering::Direct;
  sc.mapping = haptics::DeviceMapping{};
  sc.try_realtime = false;
  cloth::IntegratorConfig ic = scene.integrator;
  ic.dt = 1.0 / sc.haptic_rate;  // direct coupling steps at the haptic period
  // A cloth brought to rest is the haptic scenes' case (their preroll); the scene's start state
  // (the square released level) is pinched while it falls and swings.
  cloth::ClothState start = cloth::rest_state(model);
  if (settle_s > 0.0) start = settle(scene, model, start, 0.02, settle_s);
  const PinchSite site = settle_s > 0.0 ? middle_of_cloth(model, start) : middle_of_extent(model);
  test::TouchRig rig(cloth::ClothModel(model), pinch_trajectory(site, sc.finger.radius, seconds), sc, ic, start,
                     scene.solver, scene.pcg);
  PinchSteps p;
  rig.session->run_stepped(seconds, 0.0, [&](const haptics::HapticLoop& h, const haptics::SimWorker& w) {
    p.record(h, w);
  });
  const std::uint64_t solves = p.steps + rig.session->report().contact_revisions;
  const haptics::SessionReport rep = rig.session->report();
  const auto& st = rep.sim_step_us;
  return {{"benchmark", "step-pinch"},
          {"scene", scene.name},
          {"settled_s", settle_s},  // 0: the scene's start state, pinched as it falls
          {"pinch_across", {site.across.x(), site.across.y(), site.across.z()}},
          {"triangles", model.num_triangles()},
          {"solver", scene.solver},
          {"both_fingers_in_contact", static_cast<double>(p.both) / std::max(1L, p.ticks)},
          {"sim_step_us", {{"p50", st.quantile(0.5)}, {"p99", st.quantile(0.99)}, {"max", st.max()}}},
          {"tick_compute_us", {{"p50", rep.haptic.compute_us.quantile(0.5)}, {"p99", rep.haptic.compute_us.quantile(0.99)}}},
          {"integrator_us", {{"p50", p.integrator_us.quantile(0.5)}, {"p99", p.integrator_us.quantile(0.99)}}},
          // A step's tail that comes with long waits is the helper's core slowed, not the step's
          // own work (docs/performance.md).
          {"helper_wait_us", {{"p50", rep.sim_helper_wait_us.quantile(0.5)}, {"p99", rep.sim_helper_wait_us.quantile(0.99)},
                              {"steps_over_100us", rep.sim_helper_wait_us.fraction_at_least(100.0)}}},
          {"solver_iterations_per_step", {{"mean", p.iterations.mean()}, {"p99", p.iterations.quantile(0.99)}, {"max", p.iterations.max()}}},
          {"solves_per_step", static_cast<double>(solves) / std::max<std::uint64_t>(1, p.steps)},
          {"contact_revisions", rep.contact_revisions},
          {"steps_by_solves", {{"squeeze", p.by_solves[0]}, {"hold", p.by_solves[1]}}},
          {"integrator_p50_us_by_solves", by_solves_p50(p.integrator_us_by_solves)},
          {"integrator_us_by_phase", {{"squeeze", p.phase(0)}, {"hold", p.phase(1)}}},
          {"kept_matrix", p.kept_matrix(ic.matrix_refresh)},
          {"max_penetration_mm", rep.max_penetration * 1e3}};
}

}  // namespace hapticloth::bench
