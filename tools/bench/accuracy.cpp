// hapticloth-bench accuracy: run time against error (work-precision) of the cloth step
// (eqs. 8-9) and of the haptic coupling (section 4) on three reference scenes.
#include "accuracy.hpp"

#include <time.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <iostream>
#include <limits>

#include "app/run_summary.hpp"
#include "app/scene_file.hpp"
#include "bench_common.hpp"
#include "cloth/integrator.hpp"
#include "cloth/mesh.hpp"
#include "mock/trajectory.hpp"
#include "support/fixtures.hpp"

namespace hapticloth::bench {

using nlohmann::json;
using Vec3 = Eigen::Vector3d;

namespace {

// Error of one run against the reference run of its scene.
struct Trace {
  std::vector<std::vector<Vec3>> x;  // cloth positions at the sample times
  std::vector<Vec3> force;           // rendered force per finger, every 1 ms of loop time
  double cpu = 0.0, sim = 0.0;       // s of CPU time, s simulated
  cloth::IntegratorEvents events;
  bool finite = true;
};

bool finite_positions(const std::vector<Vec3>& x) {
  for (const auto& p : x)
    if (!p.allFinite()) return false;
  return true;
}

// The cloth alone: the hanging square released from flat (as tools/run's preroll does).
Trace run_release(const app::Scene& sc, const cloth::ClothModel& m, const RunConfig& c,
                  const std::vector<double>& samples) {
  auto integ = make_integrator(sc, m, c);
  cloth::ClothState s = cloth::rest_state(m);
  Trace tr;
  const double t0 = cpu_seconds();
  long n = 0;
  for (double ts : samples) {
    const long target = std::lround(ts / c.dt);
    for (; n < target; ++n) integ->step(s);
    tr.x.push_back(s.x);
    tr.finite = tr.finite && finite_positions(s.x);
  }
  tr.cpu = cpu_seconds() - t0;
  tr.sim = n * c.dt;
  tr.events = integ->events();
  return tr;
}

// The whole haptic session on the stepped clock: mock device on a script, the 1 kHz loop (or
// one tick per step when dt < 1 ms), direct coupling (or the local patch), the global cloth.
Trace run_haptic(const app::Scene& sc, const cloth::ClothModel& m, const cloth::ClothState& start,
                 const Vec3& device_origin, const devices::Trajectory& script, const RunConfig& c, double duration,
                 const std::vector<double>& samples) {
  const double rate = c.dt < 1e-3 ? 1.0 / c.dt : 1000.0;
  // The force's accuracy is measured, at loop rates up to 20 kHz (a tick a step below 1 ms),
  // where the scene's tactile display could not take whole samples a tick: without it.
  app::Scene force_only = sc;
  force_only.device.tactile = devices::TactileCapability{};
  MockRig rig(force_only, m, start, script, c, rate, device_origin);
  haptics::Session& session = *rig.session;

  Trace tr;
  const long per_ms = std::max(1L, std::lround(rate / 1000.0));
  long tick = 0;
  std::size_t next = 0;
  const double t0 = cpu_seconds();
  session.run_stepped(duration, c.dt >= 1e-3 ? c.dt : 1.0 / rate,
                      [&](const haptics::HapticLoop& h, const haptics::SimWorker& w) {
                        if (tick++ % per_ms == 0)
                          for (int f = 0; f < 2; ++f) tr.force.push_back(h.last_report().finger[f].force);
                        const double t = w.state().time;
                        while (next < samples.size() && t > samples[next] - 1e-7) {
                          if (std::abs(t - samples[next]) < 1e-7) tr.x.push_back(w.state().x);
                          ++next;
                        }
                      });
  tr.cpu = cpu_seconds() - t0;
  tr.sim = duration;
  tr.events = session.sim().integrator().events();
  for (const auto& x : tr.x) tr.finite = tr.finite && finite_positions(x);
  for (const auto& f : tr.force) tr.finite = tr.finite && f.allFinite();
  if (tr.x.size() != samples.size()) throw std::logic_error("accuracy: a sample time was not reached");
  return tr;
}

// RMS vertex distance (m) over the samples; `map` takes a vertex of the run to the reference's.
double position_error(const Trace& run, const Trace& ref, const std::vector<int>& map) {
  double sum = 0.0;
  long n = 0;
  for (std::size_t k = 0; k < run.x.size() && k < ref.x.size(); ++k)
    for (std::size_t i = 0; i < run.x[k].size(); ++i, ++n)
      sum += (run.x[k][i] - ref.x[k][map.empty() ? i : map[i]]).squaredNorm();
  return n ? std::sqrt(sum / n) : std::numeric_limits<double>::quiet_NaN();
}

// Relative RMS error of the rendered force over every millisecond, and the largest error (N).
std::pair<double, double> force_error(const Trace& run, const Trace& ref) {
  double num = 0.0, den = 0.0, worst = 0.0;
  for (std::size_t k = 0; k < run.force.size() && k < ref.force.size(); ++k) {
    const double e = (run.force[k] - ref.force[k]).norm();
    num += e * e;
    den += ref.force[k].squaredNorm();
    worst = std::max(worst, e);
  }
  return {den > 0.0 ? std::sqrt(num / den) : std::numeric_limits<double>::quiet_NaN(), worst};
}

// Finger 0's sideways force in a press straight down: the RMS of the rendered force's horizontal
// part over the RMS of its vertical part. A smooth membrane pushes a frictionless fingertip back
// along its own normal, nearly vertical in the middle of a drum, so what is sideways there is
// the mesh's facets (or a coupling that turns them into force: docs/contact.md).
double sideways_ratio(const Trace& tr) {
  double across = 0.0, along = 0.0;
  for (std::size_t k = 0; k < tr.force.size(); k += 2) {  // the fingers' forces interleaved
    across += tr.force[k].head<2>().squaredNorm();
    along += tr.force[k].z() * tr.force[k].z();
  }
  return along > 0.0 ? std::sqrt(across / along) : std::numeric_limits<double>::quiet_NaN();
}

// Vertex of `fine` at the rest position of each vertex of `coarse` (nested grids).
std::vector<int> nested_map(const cloth::ClothModel& coarse, const cloth::ClothModel& fine) {
  std::vector<int> map(coarse.num_vertices(), -1);
  for (int i = 0; i < coarse.num_vertices(); ++i) {
    double best = 1e300;
    for (int j = 0; j < fine.num_vertices(); ++j) {
      const double d = (coarse.rest_positions[i] - fine.rest_positions[j]).squaredNorm();
      if (d < best) best = d, map[i] = j;
    }
    if (best > 1e-18) throw std::logic_error("accuracy: grids are not nested");
  }
  return map;
}

// Pareto front of (cost, error) over the runs that finished without an abandoned step: a run is
// on the front when no other run is both cheaper and more accurate.
void mark_front(json& runs, const char* err_key, const char* flag) {
  for (auto& r : runs) {
    const double e = r.value(err_key, std::numeric_limits<double>::quiet_NaN());
    // Direct coupling at steps longer than the haptic period is shown for comparison only (the
    // server never runs it), so it is not a candidate.
    auto eligible = [&](const json& x, double ex) {
      return x["stable"].get<bool>() && std::isfinite(ex) && x["sweep"] != "direct-long-step";
    };
    bool ok = eligible(r, e);
    if (ok)
      for (const auto& o : runs) {
        const double eo = o.value(err_key, std::numeric_limits<double>::quiet_NaN());
        if (!eligible(o, eo)) continue;
        const double c = r["cpu_s_per_sim_s"], co = o["cpu_s_per_sim_s"];
        if (co <= c && eo <= e && (co < c || eo < e)) { ok = false; break; }
      }
    r[flag] = ok;
  }
}

std::vector<double> sample_times(double first, double step, double last) {
  std::vector<double> t;
  for (int k = 0; first + k * step <= last + 1e-12; ++k) t.push_back(first + k * step);
  return t;
}

// The sweep: the reference configuration, the scene's defaults, and the steps and alphas tried.
struct Sweep {
  app::Scene sc;
  bool quick = false;
  RunConfig reference, defaults;
  std::vector<double> dts, alphas;
  std::function<void(const std::string&)> say;
};

Sweep make_sweep(const AccuracyOptions& opt) {
  Sweep w;
  w.sc = main_scene(opt.source_dir);
  if (opt.refine) w.sc.haptics.coupling.refine = *opt.refine;
  w.quick = opt.quick;
  w.say = progress("accuracy", opt.verbose);
  // The reference: dt 0.05 ms (0.25 ms with --quick), alpha 0.5 (second order), PCG to 1e-10 in
  // double precision.
  w.reference.dt = w.quick ? 2.5e-4 : 5e-5;
  w.reference.alpha = 0.5;
  w.reference.tolerance = 1e-10;
  w.reference.float_matrix = false;
  w.reference.max_iterations = 5000;
  w.defaults = default_config(w.sc);
  w.dts = w.quick ? std::vector<double>{1e-3, 5e-3, 20e-3, 40e-3}
                  : std::vector<double>{0.25e-3, 0.5e-3, 1e-3, 2e-3, 5e-3, 10e-3, 20e-3, 40e-3};
  w.alphas = w.quick ? std::vector<double>{0.5, 1.0} : std::vector<double>{0.5, 0.6, 0.75, 1.0};
  return w;
}

// Solver variants at a given dt and alpha: CHOLMOD, and PCG at four tolerances in double and
// float matrices.
std::vector<RunConfig> solver_sweep(const Sweep& w, double dt, double alpha) {
  std::vector<RunConfig> v;
  RunConfig c = w.defaults;
  c.dt = dt;
  c.alpha = alpha;
  c.sweep = "solver";
  RunConfig ch = c;
  ch.solver = "cholmod";
  v.push_back(ch);
  for (double tol : std::vector<double>{1e-2, 1e-3, 1e-4, 1e-6}) {
    if (w.quick && tol < 1e-5) continue;
    for (bool fm : {false, true}) {
      if (fm && tol < 1e-5) continue;  // the float matrix is for tolerances well above 6e-8
      RunConfig p = c;
      p.tolerance = tol;
      p.float_matrix = fm;
      v.push_back(p);
    }
  }
  return v;
}

// One run of the release scene against its reference, as a JSON row.
json release_row(const RunConfig& c, const Trace& tr, const Trace& ref, const std::vector<int>& map) {
  json r = config_json(c);
  r["cpu_s_per_sim_s"] = tr.cpu / tr.sim;
  r["pos_err_mm"] = tr.finite ? 1e3 * position_error(tr, ref, map) : std::numeric_limits<double>::quiet_NaN();
  r["events"] = app::events_json(tr.events);
  r["stable"] = tr.finite && tr.events.restores == 0;
  return r;
}

// The release's configurations against the reference: dt x alpha, and the solvers at three steps.
std::vector<RunConfig> release_configs(const Sweep& w) {
  std::vector<RunConfig> cfgs;
  for (double dt : w.dts)
    for (double a : w.alphas) {
      RunConfig c = w.defaults;
      c.dt = dt, c.alpha = a, c.sweep = "dt-alpha";
      cfgs.push_back(c);
    }
  for (double dt : w.quick ? std::vector<double>{5e-3} : std::vector<double>{1e-3, 5e-3, 20e-3})
    for (const auto& c : solver_sweep(w, dt, 1.0)) cfgs.push_back(c);
  return cfgs;
}

// Mesh resolution against the finest mesh (nested grids, so vertices coincide); the reference
// for this sweep is the finest grid at dt 0.25 ms, alpha 0.5, tight solve. Adds its rows to
// `runs` and returns the reference's configuration.
RunConfig release_resolution_runs(const Sweep& w, const std::vector<double>& samples, json& runs) {
  const std::vector<int> res = w.quick ? std::vector<int>{11, 22, 44} : std::vector<int>{11, 22, 44, 88};
  const cloth::ClothModel fine = grid_model(w.sc, res.back());
  RunConfig fine_cfg = w.reference;
  fine_cfg.dt = 2.5e-4;
  fine_cfg.resolution = res.back();
  w.say("release: reference run of the resolution sweep (" + std::to_string(fine.num_triangles()) + " triangles)");
  const Trace fine_ref = run_release(w.sc, fine, fine_cfg, samples);
  for (int n : std::vector<int>(res.begin(), res.end() - (w.quick ? 1 : 0))) {
    const cloth::ClothModel mm = grid_model(w.sc, n);
    const std::vector<int> map = nested_map(mm, fine);
    // the default tolerance, and 10x tighter: does the tolerance show on finer meshes?
    for (double tol : {w.defaults.tolerance, 0.1 * w.defaults.tolerance}) {
      RunConfig c = w.defaults;
      c.resolution = n;
      c.tolerance = tol;
      c.sweep = "resolution";
      w.say("release: " + describe(c));
      runs.push_back(release_row(c, run_release(w.sc, mm, c, samples), fine_ref, map));
      runs.back()["triangles"] = mm.num_triangles();
    }
  }
  return fine_cfg;
}

// The cloth alone: the hanging square released from flat, every configuration against the
// reference, and the mesh resolution against the finest mesh.
json release_scene(const Sweep& w) {
  const double T = w.quick ? 0.6 : 1.0;
  const auto samples = sample_times(0.2, 0.2, T);  // multiples of every dt in the sweep
  const cloth::ClothModel m = grid_model(w.sc, 22);
  w.say("release: reference run");
  const Trace ref = run_release(w.sc, m, w.reference, samples);
  json runs = json::array();
  for (const auto& c : release_configs(w)) {
    w.say("release: " + describe(c));
    runs.push_back(release_row(c, run_release(w.sc, m, c, samples), ref, {}));
  }
  const RunConfig fine_cfg = release_resolution_runs(w, samples, runs);
  mark_front(runs, "pos_err_mm", "pareto");
  return {{"what", "hanging square (968 triangles) released from flat, " + std::to_string(samples.size()) +
                       " samples over " + fmt(T) + " s; error: RMS vertex distance"},
          {"reference_cpu_s_per_sim_s", ref.cpu / ref.sim},
          {"resolution_reference", config_json(fine_cfg)},
          {"runs", runs}};
}

// A haptic scene: the cloth, its start, the device's origin and script.
struct HapticScene {
  std::string name, what;
  cloth::ClothModel model;
  cloth::ClothState start;
  Vec3 origin = Vec3::Zero();
  devices::Trajectory script{2};
  bool straight_down = false;  // finger 0 presses straight down (its sideways force is reported)
};

// The press: a 0.3 m square of the same denim, pinned on its four edges and pre-stretched by 3%
// (an embroidery hoop: a membrane without bending resists a press only through tension), under
// gravity; finger 0 comes down on it at (3, 2) mm from the centre, presses 4 mm into it, holds
// and leaves. Finger 1 stays away.
HapticScene press_scene(const Sweep& w) {
  HapticScene p;
  p.name = "press";
  p.what = "press 4 mm into a pre-stretched 0.3 m drum (800 triangles)";
  p.model = test::square_cloth(w.sc.material, {"top", "bottom", "left", "right"});
  cloth::ClothState stretched = cloth::rest_state(p.model);
  for (auto& x : stretched.x) x.head<2>() *= 1.03;
  p.start = settle(w.sc, p.model, stretched, w.defaults.dt, 2.0);  // 2 s: settles the sag
  const double r = w.sc.haptics.finger.radius, x = 0.003, y = 0.002;
  double zc = 0.0;  // the sagged cloth under the finger
  for (int i = 0; i < p.model.num_vertices(); ++i)
    if ((p.start.x[i].head<2>() - Eigen::Vector2d(x, y)).norm() < 0.01) zc = std::min(zc, p.start.x[i].z());
  for (const auto& [t, z] : std::vector<std::pair<double, double>>{
           {0.0, zc + 0.02}, {0.1, zc + 0.02}, {0.5, zc + r - 0.004}, {0.9, zc + r - 0.004}, {1.2, zc + 0.02}})
    p.script.add(0, t, Vec3(x, y, z));
  p.script.add(1, 0.0, Vec3(0.1, 0.1, 0.08));
  p.straight_down = true;
  return p;
}

// The pinch-lift on the hanging square at rest (the scene's preroll, CHOLMOD at dt 1 ms).
HapticScene pinch_scene(const Sweep& w, const std::string& source_dir) {
  HapticScene p;
  p.name = "pinch";
  p.what = "pinch-lift on the hanging square at rest (tools/scenes/accuracy_pinch.toml)";
  p.model = app::build_model(w.sc);
  p.start = settle(w.sc, p.model, cloth::rest_state(p.model), w.defaults.dt, w.sc.preroll);
  p.origin = w.sc.haptics.mapping.origin;
  p.script = devices::load_trajectory(source_dir + "/tools/scenes/accuracy_pinch.toml", 2);
  return p;
}

// dt <= the haptic period: direct coupling (what the server runs when the step fits); longer
// steps: the multirate path with each local model (4.2), and for comparison the direct
// coupling, which the server does not run at such steps (it shortens dt instead).
std::vector<RunConfig> haptic_configs(const Sweep& w) {
  std::vector<RunConfig> cfgs;
  for (double dt : w.dts) {
    if (dt > 1e-3) continue;
    for (double a : w.quick ? std::vector<double>{1.0} : std::vector<double>{0.5, 1.0}) {
      RunConfig c = w.defaults;
      c.dt = dt, c.alpha = a, c.sweep = "dt-alpha";
      cfgs.push_back(c);
    }
  }
  for (double dt : w.dts) {
    if (dt <= 1e-3) continue;
    RunConfig c = w.defaults;
    c.dt = dt, c.multirate = true, c.sweep = "local-response";
    cfgs.push_back(c);
    c.local_model = haptics::LocalModel::Patch, c.sweep = "local-patch";
    cfgs.push_back(c);
    c.multirate = false, c.sweep = "direct-long-step";
    cfgs.push_back(c);
  }
  if (!w.quick)
    for (const auto& c : solver_sweep(w, 1e-3, 1.0)) cfgs.push_back(c);
  return cfgs;
}

// One haptic run against its reference, as a JSON row.
json haptic_row(const RunConfig& c, const Trace& tr, const Trace& ref, bool straight_down) {
  json r = config_json(c);
  r["cpu_s_per_sim_s"] = tr.cpu / tr.sim;
  const auto [fe, fmax] = force_error(tr, ref);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  r["pos_err_mm"] = tr.finite ? 1e3 * position_error(tr, ref, {}) : nan;
  r["force_err_rel"] = tr.finite ? fe : nan;
  r["force_err_max_n"] = tr.finite ? fmax : nan;
  r["events"] = app::events_json(tr.events);
  r["stable"] = tr.finite && tr.events.restores == 0;
  if (straight_down) r["sideways_ratio"] = sideways_ratio(tr);
  return r;
}

// Every haptic configuration of a scene against its reference run.
json haptic_scene(const Sweep& w, const HapticScene& p) {
  const double T = p.script.duration();
  const auto samples = sample_times(0.2, 0.2, T - 0.04);
  w.say(p.name + ": reference run");
  const Trace ref = run_haptic(w.sc, p.model, p.start, p.origin, p.script, w.reference, T, samples);
  json runs = json::array();
  for (const auto& c : haptic_configs(w)) {
    w.say(p.name + ": " + describe(c));
    runs.push_back(haptic_row(c, run_haptic(w.sc, p.model, p.start, p.origin, p.script, c, T, samples), ref,
                              p.straight_down));
  }
  mark_front(runs, "force_err_rel", "pareto");
  mark_front(runs, "pos_err_mm", "pareto_position");
  double fmax_ref = 0.0;
  for (const auto& f : ref.force) fmax_ref = std::max(fmax_ref, f.norm());
  json out = {{"what", p.what + ", " + fmt(T) + " s; error: relative RMS of the rendered force every 1 ms, RMS vertex "
                       "distance at " + std::to_string(samples.size()) + " samples"},
              {"reference_cpu_s_per_sim_s", ref.cpu / ref.sim},
              {"reference_max_force_n", fmax_ref},
              {"runs", runs}};
  if (p.straight_down) out["reference_sideways_ratio"] = sideways_ratio(ref);
  return out;
}

}  // namespace

json accuracy(const AccuracyOptions& opt) {
  const Sweep w = make_sweep(opt);
  json out = {{"benchmark", "accuracy"},
              {"quick", w.quick},
              {"reference", config_json(w.reference)},
              {"defaults", config_json(w.defaults)}};
  out["scenes"]["release"] = release_scene(w);
  out["scenes"]["press"] = haptic_scene(w, press_scene(w));
  out["scenes"]["pinch"] = haptic_scene(w, pinch_scene(w, opt.source_dir));
  return out;
}

}  // namespace hapticloth::bench
