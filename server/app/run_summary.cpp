#include "app/run_summary.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <sstream>

#include <nlohmann/json.hpp>

namespace hapticloth::app {

Percentiles percentiles(std::vector<double> v) {
  Percentiles p;
  if (v.empty()) return p;
  std::sort(v.begin(), v.end());
  auto at = [&](double q) {
    const size_t i = static_cast<size_t>(std::ceil(q * static_cast<double>(v.size()))) - 1;
    return v[std::min(i, v.size() - 1)];
  };
  p.median = at(0.5);
  p.p99 = at(0.99);
  p.max = v.back();
  return p;
}

RunSummary run_headless(const Scene& scene, long steps, const std::atomic<bool>* stop) {
  const cloth::ClothModel model = build_model(scene);
  auto integ = make_integrator(scene, model);
  cloth::ClothState s = cloth::rest_state(model);
  std::vector<double> t_step, t_asm, t_solve;
  t_step.reserve(steps);
  t_asm.reserve(steps);
  t_solve.reserve(steps);
  double iters = 0;
  const long asked = steps;
  const auto w0 = std::chrono::steady_clock::now();
  for (long k = 0; k < asked; ++k) {
    if (stop && stop->load(std::memory_order_relaxed)) {
      steps = k;
      break;
    }
    integ->step(s);
    const auto& tm = integ->last_timing();
    t_step.push_back(tm.total_ms);
    t_asm.push_back(tm.assemble_ms);
    t_solve.push_back(tm.solve_ms);
    iters += tm.iterations;
  }
  RunSummary r;
  r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - w0).count();
  r.scene = scene.name;
  r.solver = integ->solver().name();
  if (r.solver == "pcg") r.preconditioner = cloth::to_string(scene.pcg.preconditioner);
  r.simd = cloth::to_string(integ->simd_level());
  r.lanes = integ->lanes();
  r.triangles = model.num_triangles();
  r.vertices = model.num_vertices();
  r.dt = scene.integrator.dt;
  r.alpha = scene.integrator.alpha;
  r.steps = steps;
  if (steps < asked) r.steps_asked_when_stopped = asked;
  r.simulated_s = s.time;
  r.step_ms = percentiles(t_step);
  r.assemble_ms = percentiles(t_asm);
  r.solve_ms = percentiles(t_solve);
  r.iterations_mean = steps ? iters / steps : 0.0;
  const cloth::Vec3 up = scene.integrator.gravity.norm() > 0 ? cloth::Vec3(-scene.integrator.gravity.normalized())
                                                             : cloth::Vec3(0, 0, 1);
  r.lowest_height = 1e300;
  for (int i = 0; i < model.num_vertices(); ++i) {
    r.finite = r.finite && s.x[i].allFinite() && s.v[i].allFinite();
    r.lowest_height = std::min(r.lowest_height, s.x[i].dot(up));
  }
  r.final_kinetic_energy = cloth::compute_energies(model, s, scene.integrator.gravity).kinetic;
  r.events = integ->events();
  return r;
}

nlohmann::json events_json(const cloth::IntegratorEvents& e) {
  return {{"non_finite", e.non_finite},
          {"solver_not_converged", e.solver_not_converged},
          {"solver_error", e.solver_error},
          {"not_positive_definite", e.not_positive_definite},
          {"jacobian_fallbacks", e.jacobian_fallbacks},
          {"energy_explosions", e.energy_explosions},
          {"alpha_fallbacks", e.alpha_fallbacks},
          {"retries", e.retries},
          {"restores", e.restores}};
}

std::string RunSummary::to_json() const {
  nlohmann::json j;
  j["scene"] = scene;
  j["solver"] = solver;
  if (!preconditioner.empty()) j["preconditioner"] = preconditioner;
  j["simd"] = simd;
  j["lanes"] = lanes;
  j["triangles"] = triangles;
  j["vertices"] = vertices;
  j["dt"] = dt;
  j["alpha"] = alpha;
  j["steps"] = steps;
  j["simulated_s"] = simulated_s;
  j["ms_per_step_median"] = step_ms.median;
  j["ms_per_step_p99"] = step_ms.p99;
  j["ms_per_step_max"] = step_ms.max;
  j["assemble_ms_median"] = assemble_ms.median;
  j["solve_ms_median"] = solve_ms.median;
  j["solver_iterations_mean"] = iterations_mean;
  j["final_kinetic_energy_j"] = final_kinetic_energy;
  j["lowest_vertex_height_m"] = lowest_height;
  j["finite"] = finite;
  j["wall_s"] = wall_s;
  j["events"] = events_json(events);
  j["stopped"] = steps_asked_when_stopped ? nlohmann::json(stopped) : nlohmann::json(nullptr);
  return j.dump();
}

std::string RunSummary::to_text() const {
  std::ostringstream os;
  os << std::fixed;
  os << "scene            " << scene << " (" << triangles << " triangles, " << vertices
     << " vertices)\n";
  os << "integrator       dt " << std::setprecision(4) << dt * 1e3 << " ms, alpha "
     << std::setprecision(2) << alpha << ", solver " << solver
     << (preconditioner.empty() ? "" : " (" + preconditioner + ")") << "\n";
  os << "element pass     " << simd << ", " << lanes << " lanes\n";
  os << "steps            " << steps << " (" << std::setprecision(3) << simulated_s
     << " s simulated in " << wall_s << " s)\n";
  os << "ms per step      median " << std::setprecision(4) << step_ms.median << ", p99 "
     << step_ms.p99 << ", max " << step_ms.max << "\n";
  os << "  assembly       median " << assemble_ms.median << " ms\n";
  os << "  solve          median " << solve_ms.median << " ms (" << std::setprecision(1)
     << iterations_mean << " iterations on average)\n";
  os << std::scientific << std::setprecision(3);
  os << "final kinetic energy  " << final_kinetic_energy << " J\n";
  os << std::fixed << std::setprecision(4);
  os << "lowest vertex height  " << lowest_height << " m\n";
  os << "state finite     " << (finite ? "yes" : "NO") << "\n";
  os << "events           " << events.total() << " (non-finite " << events.non_finite
     << ", solver " << events.solver_not_converged + events.solver_error << ", not-SPD "
     << events.not_positive_definite << ", energy " << events.energy_explosions << ", retries "
     << events.retries << ", restores " << events.restores << ")\n";
  if (steps_asked_when_stopped) os << "stopped          " << stopped << "\n";
  return os.str();
}

}  // namespace hapticloth::app
