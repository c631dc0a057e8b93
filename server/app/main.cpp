// hapticloth-server: loads a scene and runs the cloth simulation, headless or with a haptic
// device (mock, udp, replay, ...) in the 1 kHz haptic loop.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "cli_checks.hpp"

#include "app/run_summary.hpp"
#include "app/scene_file.hpp"
#include "app/serve.hpp"
#include "app/stop_signal.hpp"
#include "app/toml_file.hpp"
#include "registry.hpp"

int main(int argc, char** argv) {
  using namespace hapticloth;
  CLI::App cli{"hapticloth-server: cloth simulation and haptic rendering server (HAPTEX model)"};
  std::string scene_path;
  double duration = -1.0;
  bool headless = false, json = false, fast = false, no_rt = false;
  std::string solver, device, script, record, replay, udp_bind;
  double dt = -1.0, alpha = -1.0;
  std::string known;
  for (const auto& n : devices::device_names()) known += (known.empty() ? "" : "|") + n;
  cli.add_option("--scene", scene_path, "scene file (TOML)")->required();
  cli.add_option("--duration", duration, "seconds to run (default: the scene's duration)")
      ->check(opts::positive(1e6, "s"));
  cli.add_flag("--headless", headless, "no device: step as fast as possible and print a summary");
  cli.add_flag("--json", json, "print the summary as one JSON object");
  cli.add_option("--solver", solver, "override the scene's solver (pcg, cholmod)");
  cli.add_option("--dt", dt, "override the scene's time step (s)")->check(opts::positive(1.0, "s"));
  cli.add_option("--alpha", alpha, "override the scene's alpha in [0.5, 1]")->check(opts::number_in(0.5, 1.0));
  cli.add_option("--device", device, "haptic device driver (" + known + "); overrides [device] driver");
  cli.add_option("--script", script, "mock: fingertip trajectory (.toml primitives or .csv time,finger,x,y,z)");
  cli.add_option("--record", record, "mock/udp: write the device log (CSV) here")->check(opts::writable_file());
  cli.add_option("--replay", replay, "replay: the device log to play back");
  cli.add_option("--udp-bind", udp_bind, "udp: HOST:PORT to receive state packets on (default 127.0.0.1:47800)");
  cli.add_flag("--fast", fast, "stepped clock: run the haptic session as fast as possible");
  cli.add_flag("--no-realtime", no_rt, "do not ask for SCHED_FIFO / mlockall");
  // --- transport
  transport::TransportOptions tr;
  bool no_zenoh = false;
  cli.add_option("--name", tr.server_name, "server name: key expressions hapticloth/<name>/... (default: default)");
  auto* zc = cli.add_option("--zenoh-config", tr.zenoh_config, "zenoh JSON5 config file (default: peer, listen tcp/127.0.0.1:7447, no scouting)");
  auto* zl = cli.add_option("--zenoh-listen", tr.zenoh_listen, "zenoh endpoint to listen on without a config file (default tcp/127.0.0.1:7447)");
  cli.add_flag("--no-zenoh", no_zenoh, "do not publish over zenoh");
  cli.add_option("--lcm-url", tr.lcm_url, "also publish on this LCM provider (e.g. udpm://239.255.76.67:7667?ttl=0)");
  bool no_lcm_log = false;
  cli.add_option("--lcm-log", tr.lcm_log, "LCM log of the run (every message); default out/<scene>.lcm")
      ->check(opts::writable_file());
  cli.add_flag("--no-lcm-log", no_lcm_log, "do not write the LCM log");
  cli.add_option("--cloth-rate", tr.cloth_rate, "Hz, cloth state messages (default 60)")
      ->check(opts::positive(1000.0, "Hz"));
  cli.add_option("--max-command-speed", tr.max_command_speed, "m/s, fastest injected fingertip trajectory (default 1)")
      ->check(opts::positive(100.0, "m/s"));
  // --- end transport
  if (const int rc = opts::parse(cli, argc, argv); rc >= 0) return rc;

  try {
    app::Scene scene = app::load_scene(scene_path);
    if (!solver.empty()) scene.solver = solver;
    if (dt > 0) scene.integrator.dt = dt;
    if (alpha > 0) scene.integrator.alpha = alpha;
    scene.integrator.validate();
    if (headless) {
      if (duration <= 0) duration = scene.duration;
      const long steps = std::lround(duration / scene.integrator.dt);
      if (steps < 1) {
        std::cerr << "hapticloth-server: --duration " << duration << " s is shorter than one step (dt "
                  << scene.integrator.dt << " s)\n";
        return 2;
      }
      const app::RunSummary r = app::run_headless(scene, steps);
      std::cout << (json ? r.to_json() + "\n" : r.to_text());
      return r.finite ? 0 : 1;
    }
    if (!device.empty()) {
      scene.device.driver = device;
      scene.has_device = true;
    }
    if (!scene.has_device) {
      std::cerr << "hapticloth-server: no device: give --device (" << known
                << ") or a [device] table in the scene, or run --headless\n";
      return 2;
    }
    if (!script.empty()) scene.device.script = script;
    if (!record.empty()) scene.device.record_path = record;
    if (!replay.empty()) scene.device.replay_path = replay;
    if (!udp_bind.empty()) scene.device.udp_bind = udp_bind;
    if (no_rt) scene.haptics.try_realtime = false;
    if (no_lcm_log) {
      tr.lcm_log.clear();
    } else if (tr.lcm_log.empty()) {
      // By default every session leaves a real LCM log (file:// provider) that lcm-logplayer
      // and Python's lcm.EventLog read, in out/ under the current directory.
      std::error_code ec;
      std::filesystem::create_directories("out", ec);
      const std::string path = "out/" + scene.name + ".lcm";
      if (!ec && std::ofstream(path, std::ios::app)) {
        tr.lcm_log = path;
      } else {
        std::cerr << "hapticloth-server: cannot write " << path << "; running without the LCM log\n";
      }
    }
    app::ServeOptions so;
    so.stop = &app::install_stop_signals();
    so.duration = duration;
    so.realtime = !fast;
    so.json = json;
    tr.zenoh = !no_zenoh;  // --- transport
    so.transport = tr;
    so.transport_required = zc->count() > 0 || zl->count() > 0;
    return app::serve(scene, so, std::cout);
  } catch (const std::exception& e) {  // app::ConfigError (a bad scene or option) and the rest
    std::cerr << "hapticloth-server: " << e.what() << "\n";
    return 2;
  }
}
