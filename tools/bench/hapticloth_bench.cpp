// hapticloth-bench: benchmarks that print machine-readable results.
//   hapticloth-bench step --scene FILE [--solver cholmod|pcg] [--dt S] [--alpha A] [--steps N] --json
#include <cmath>
#include <iostream>

#include <CLI/CLI.hpp>

#include "app/run_summary.hpp"
#include "app/scene_file.hpp"
#include "app/toml_file.hpp"

int main(int argc, char** argv) {
  using namespace hapticloth;
  CLI::App cli{"hapticloth-bench: benchmarks with machine-readable output"};
  cli.require_subcommand(1);

  auto* step = cli.add_subcommand("step", "time the cloth step of a scene, headless");
  std::string scene_path, solver;
  double dt = -1, alpha = -1, tol = -1;
  long steps = 2000;
  bool json = false;
  step->add_option("--scene", scene_path, "scene file (TOML)")->required();
  step->add_option("--solver", solver, "pcg, cholmod or cholmod-supernodal (default: the scene's)");
  step->add_option("--dt", dt, "time step, s (default: the scene's)");
  step->add_option("--alpha", alpha, "alpha in [0.5, 1] (default: the scene's)");
  step->add_option("--pcg-tolerance", tol, "relative residual of the PCG solve");
  step->add_option("--steps", steps, "number of steps from the rest state")->check(CLI::PositiveNumber);
  step->add_flag("--json", json, "one JSON object on stdout");
  CLI11_PARSE(cli, argc, argv);

  try {
    app::Scene scene = app::load_scene(scene_path);
    if (!solver.empty()) scene.solver = solver;
    if (dt > 0) scene.integrator.dt = dt;
    if (alpha > 0) scene.integrator.alpha = alpha;
    if (tol > 0) scene.pcg.tolerance = tol;
    scene.integrator.validate();
    const app::RunSummary r = app::run_headless(scene, steps);
    std::cout << (json ? r.to_json() + "\n" : r.to_text());
    return r.finite ? 0 : 1;
  } catch (const std::exception& e) {
    std::cerr << "hapticloth-bench: " << e.what() << "\n";
    return 2;
  }
}
