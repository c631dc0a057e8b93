// Shared pieces of the accuracy and stability benchmarks: one run's settings, CPU clock,
// the hanging square at any resolution.
#pragma once

#include <time.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <iostream>
#include <stdexcept>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "app/scene_file.hpp"
#include "cloth/integrator.hpp"
#include "hal/handle.hpp"
#include "haptics/session.hpp"
#include "mock/mock_device.hpp"
#include "cloth/mesh.hpp"
#include "cloth/solver.hpp"

namespace hapticloth::bench {

/// The main job's scene (tools/scenes/hanging_square.toml) of the source tree `source_dir`.
inline app::Scene main_scene(const std::string& source_dir) {
  return app::load_scene(source_dir + "/tools/scenes/hanging_square.toml");
}

/// A benchmark's progress lines on stderr ("NAME: what"), when `verbose`.
inline std::function<void(const std::string&)> progress(const std::string& name, bool verbose) {
  return [name, verbose](const std::string& s) {
    if (verbose) std::cerr << name << ": " << s << std::endl;
  };
}

/// Settings of one run (what a sweep varies).
struct RunConfig {
  double dt = 1e-3;
  double alpha = 1.0;
  std::string solver = "pcg";
  double tolerance = 1e-4;
  bool float_matrix = true;
  int max_iterations = 300;
  int resolution = 22;      ///< quads per side of the 0.5 m square
  bool multirate = false;   ///< the multirate path, with `local_model`
  haptics::LocalModel local_model = haptics::LocalModel::Response;
  double stiffness_scale = 1.0;
  std::string sweep;        ///< which sweep the run belongs to
};

/// The scene's own settings (what the server runs by default).
inline RunConfig default_config(const app::Scene& sc) {
  RunConfig c;
  c.dt = sc.integrator.dt;
  c.alpha = sc.integrator.alpha;
  c.solver = sc.solver;
  c.tolerance = sc.pcg.tolerance;
  c.float_matrix = sc.pcg.single_precision_matrix;
  c.max_iterations = sc.pcg.max_iterations;
  c.sweep = "defaults";
  return c;
}

// Where the multirate path's rendered force puts finger f's proxy in the global cloth: the
// fingertip plus the stretch of the spring the step solved with, K (with local refinement the
// scene's k in series with the compliance the coarse mesh lacks). The reported proxy, tip + F / k,
// is the refined child's sphere, c F deeper than the global cloth by design (docs/contact.md,
// 'Local refinement under the fingertips'); without a step's spring (the patch model solves no
// proxies), the reported one.
inline Eigen::Vector3d proxy_in_global_cloth(const haptics::FingerReport& r, const cloth::Integrator& step, int f) {
  const auto& proxies = step.proxies();
  if (f >= static_cast<int>(proxies.size()) || !(proxies[f].stiffness > 0.0)) return r.proxy;
  return r.position + proxies[f].stiffness_matrix().inverse() * r.force;
}

inline double cpu_seconds() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

inline std::string fmt(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}

inline std::string describe(const RunConfig& c) {
  std::string s = "dt " + fmt(c.dt * 1e3) + " ms, alpha " + fmt(c.alpha) + ", " + c.solver;
  if (c.solver == "pcg") s += " tol " + fmt(c.tolerance) + (c.float_matrix ? " float" : " double");
  if (c.resolution != 22) s += ", " + std::to_string(2 * c.resolution * c.resolution) + " triangles";
  if (c.multirate) s += std::string(", multirate (") + haptics::to_string(c.local_model) + ")";
  if (c.stiffness_scale != 1.0) s += ", stiffness x" + fmt(c.stiffness_scale);
  return s;
}

inline nlohmann::json config_json(const RunConfig& c) {
  nlohmann::json j = {{"dt_ms", c.dt * 1e3}, {"alpha", c.alpha}, {"solver", c.solver},
                      {"triangles", 2 * c.resolution * c.resolution}, {"sweep", c.sweep},
                      {"label", describe(c)}};
  if (c.solver == "pcg") {
    j["pcg_tolerance"] = c.tolerance;
    j["pcg_float_matrix"] = c.float_matrix;
  }
  if (c.multirate) j["local_model"] = haptics::to_string(c.local_model);
  if (c.stiffness_scale != 1.0) j["stiffness_scale"] = c.stiffness_scale;
  return j;
}

inline std::unique_ptr<cloth::LinearSolver> make_solver(const app::Scene&, const RunConfig& c) {
  cloth::PcgOptions po;
  po.tolerance = c.tolerance;
  po.single_precision_matrix = c.float_matrix;
  po.max_iterations = c.max_iterations;
  return cloth::make_solver(c.solver, po);
}

inline std::unique_ptr<cloth::Integrator> make_integrator(const app::Scene& sc,
                                                          const cloth::ClothModel& m,
                                                          const RunConfig& c) {
  cloth::IntegratorConfig ic = sc.integrator;
  ic.dt = c.dt;
  ic.alpha = c.alpha;
  ic.validate();
  return std::make_unique<cloth::Integrator>(m, ic, make_solver(sc, c));
}

/// The hanging square of tools/scenes/hanging_square.toml (0.5 m, flat at z = 0, top edge
/// pinned) with n x n quads and the scene's material scaled by `stiffness_scale`.
inline cloth::ClothModel grid_model(const app::Scene& sc, int n, double stiffness_scale = 1.0) {
  cloth::GridSpec g;
  g.width = g.height = 0.5;
  g.nx = g.ny = n;
  g.origin = {-0.25, -0.25, 0.0};
  const cloth::Mesh mesh = cloth::make_grid(g);
  cloth::Material mat = sc.material;
  for (auto* c : {&mat.weft, &mat.warp, &mat.shear})
    for (auto& row : c->B)
      for (auto& b : row) b *= stiffness_scale;
  return cloth::build_model(mesh, mat, cloth::grid_edge(mesh, "top"));
}

/// `s` brought to rest: `seconds` of CHOLMOD steps of `dt` (alpha 1), then zero velocity and
/// time 0 (the start state of a benchmark run).
inline cloth::ClothState settle(const app::Scene& sc, const cloth::ClothModel& m, cloth::ClothState s,
                                double dt, double seconds) {
  RunConfig pre;
  pre.dt = dt;
  pre.solver = "cholmod";
  auto integ = make_integrator(sc, m, pre);
  const long n = std::lround(seconds / dt);
  for (long k = 0; k < n; ++k) integ->step(s);
  s.time = 0.0;
  for (auto& v : s.v) v.setZero();
  return s;
}

/// A haptic session on the stepped clock with the mock device playing `script`: the scene's
/// [haptics] and [device] settings with the run's dt, alpha, solver and coupling.
struct MockRig {
  devices::DeviceHandle dev;
  std::unique_ptr<haptics::Session> session;
  MockRig(const app::Scene& sc, const cloth::ClothModel& m, const cloth::ClothState& start,
          const devices::Trajectory& script, const RunConfig& c, double haptic_rate,
          const Eigen::Vector3d& device_origin)
      : dev(make_device(sc, script, haptic_rate)) {
    if (const std::string e = dev.configure(); !e.empty()) throw std::runtime_error("mock device: " + e);
    haptics::SessionConfig hc = sc.haptics;
    hc.try_realtime = false;
    hc.haptic_rate = haptic_rate;
    hc.rendering = haptics::rendering(c.multirate, c.local_model);
    hc.mapping.origin = device_origin;
    cloth::IntegratorConfig ic = sc.integrator;
    ic.dt = c.dt;
    ic.alpha = c.alpha;
    ic.validate();
    session = std::make_unique<haptics::Session>(m, ic, make_solver(sc, c), start, dev, hc);
  }

 private:
  static std::unique_ptr<devices::Device> make_device(const app::Scene& sc, const devices::Trajectory& script,
                                                      double rate) {
    devices::DeviceOptions o = sc.device;
    o.rate = rate;
    return std::make_unique<devices::MockDevice>(o, script);
  }
};

}  // namespace hapticloth::bench
