// Headless runs of a scene and their summary (shared by the server and the benchmark).
#pragma once

#include <atomic>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "app/scene_file.hpp"

namespace hapticloth::app {

struct Percentiles {
  double median = 0, p99 = 0, max = 0;
};
/// Percentiles of a sample (copied; the input is left as is).
Percentiles percentiles(std::vector<double> v);

struct RunSummary {
  std::string scene, solver;
  std::string preconditioner;  ///< the PCG's ("ssor", "block-jacobi"); empty for a direct solver
  std::string simd;            ///< the element pass's instruction level (cloth/simd_level.hpp)
  int lanes = 0;               ///< and the doubles in its lanes
  int triangles = 0, vertices = 0;
  double dt = 0, alpha = 0, simulated_s = 0;
  long steps = 0;
  Percentiles step_ms, assemble_ms, solve_ms;
  double iterations_mean = 0;
  double final_kinetic_energy = 0;  ///< J
  double lowest_height = 0;         ///< m, lowest vertex along -gravity (z when g is -z)
  double wall_s = 0;
  cloth::IntegratorEvents events;
  bool finite = true;
  /// A stop signal ended the run after `steps` of these (0: it ran them all); `stopped` says by
  /// what ("by SIGTERM after 1234 of 10000 steps"), filled by the caller that knows the signal.
  long steps_asked_when_stopped = 0;
  std::string stopped;
  std::string to_json() const;
  std::string to_text() const;
};

/// The integrator's event counters as one JSON object, a key per counter (the run summary's
/// "events" and the benchmarks').
nlohmann::json events_json(const cloth::IntegratorEvents& e);

/// Steps the scene headless `steps` times, as fast as possible; fewer if `*stop` turns true.
RunSummary run_headless(const Scene& scene, long steps, const std::atomic<bool>* stop = nullptr);

}  // namespace hapticloth::app
