// hapticloth-server: loads a scene and runs the cloth simulation.
#include <cmath>
#include <iostream>

#include <CLI/CLI.hpp>

#include "app/run_summary.hpp"
#include "app/scene_file.hpp"
#include "app/toml_file.hpp"

int main(int argc, char** argv) {
  using namespace hapticloth;
  CLI::App cli{"hapticloth-server: cloth simulation server (HAPTEX model)"};
  std::string scene_path;
  double duration = -1.0;
  bool headless = false, json = false;
  std::string solver;
  double dt = -1.0, alpha = -1.0;
  cli.add_option("--scene", scene_path, "scene file (TOML)")->required();
  cli.add_option("--duration", duration, "simulated seconds (default: the scene's duration)");
  cli.add_flag("--headless", headless, "no device: step as fast as possible and print a summary");
  cli.add_flag("--json", json, "print the summary as one JSON object");
  cli.add_option("--solver", solver, "override the scene's solver (pcg, cholmod)");
  cli.add_option("--dt", dt, "override the scene's time step (s)");
  cli.add_option("--alpha", alpha, "override the scene's alpha in [0.5, 1]");
  CLI11_PARSE(cli, argc, argv);

  try {
    app::Scene scene = app::load_scene(scene_path);
    if (!solver.empty()) scene.solver = solver;
    if (dt > 0) scene.integrator.dt = dt;
    if (alpha > 0) scene.integrator.alpha = alpha;
    scene.integrator.validate();
    if (duration <= 0) duration = scene.duration;
    if (!headless) {
      std::cerr << "hapticloth-server: no haptic device driver is configured; run with "
                   "--headless to step the cloth without a device\n";
      return 2;
    }
    const long steps = std::lround(duration / scene.integrator.dt);
    const app::RunSummary r = app::run_headless(scene, steps);
    std::cout << (json ? r.to_json() + "\n" : r.to_text());
    return r.finite ? 0 : 1;
  } catch (const app::ConfigError& e) {
    std::cerr << "hapticloth-server: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "hapticloth-server: " << e.what() << "\n";
    return 2;
  }
}
