// hapticloth-server: loads a scene and runs the cloth simulation, headless or with a haptic
// device (mock, udp, replay, ...) in the 1 kHz haptic loop.
#include <cmath>
#include <csignal>
#include <filesystem>
#include <iostream>

#include <unistd.h>

#include "cli_checks.hpp"

#include "app/mesh_budget.hpp"
#include "app/output_claim.hpp"
#include "app/run_summary.hpp"
#include "app/scene_file.hpp"
#include "app/serve.hpp"
#include "app/stop_signal.hpp"
#include "app/toml_file.hpp"
#include "registry.hpp"
#include "transport/foxglove_sink.hpp"

namespace {

using namespace hapticloth;

// The command line: the scene, what overrides it, and the transports.
struct Args {
  std::string scene_path;
  double duration = -1.0;
  bool headless = false, json = false, fast = false, no_rt = false;
  std::string solver, device, script, record, replay, udp_bind, clock;
  double dt = -1.0, alpha = -1.0;
  std::string known_drivers;  // "mock|replay|..."
  transport::TransportOptions tr;
  bool no_zenoh = false, no_lcm_log = false;
  const CLI::Option* zenoh_config = nullptr;
  const CLI::Option* zenoh_listen = nullptr;
};

void add_run_options(CLI::App& cli, Args& a) {
  for (const auto& n : devices::device_names())
    a.known_drivers += (a.known_drivers.empty() ? "" : "|") + n;
  cli.add_option("--scene", a.scene_path, "scene file (TOML)")->required();
  cli.add_option("--duration", a.duration, "seconds to run (default: the scene's duration)")
      ->check(opts::positive(1e6, "s"));
  cli.add_flag("--headless", a.headless, "no device: step as fast as possible and print a summary");
  cli.add_flag("--json", a.json, "print the summary as one JSON object");
  cli.add_option("--solver", a.solver, "override the scene's solver (pcg, cholmod, cholmod-supernodal)")
      ->check(CLI::IsMember(app::kSolvers));
  cli.add_option("--dt", a.dt, "override the scene's time step (s)")
      ->check(opts::number_in(app::kMinDt, app::kMaxDt, false, "s"));
  cli.add_option("--alpha", a.alpha, "override the scene's alpha in [0.5, 1]")->check(opts::number_in(0.5, 1.0));
  cli.add_option("--device", a.device, "haptic device driver (" + a.known_drivers + "); overrides [device] driver")
      ->check(CLI::IsMember(devices::device_names()));
  cli.add_option("--script", a.script, "mock: fingertip trajectory (.toml primitives or .csv time,finger,x,y,z)")
      ->check(opts::non_empty());
  cli.add_option("--record", a.record, "mock/udp: write the device log (CSV) here")->check(opts::writable_file());
  cli.add_option("--replay", a.replay, "replay: the device log to play back")->check(opts::non_empty());
  cli.add_option("--udp-bind", a.udp_bind, "udp: HOST:PORT to receive state packets on (default 127.0.0.1:47800)")
      ->check(opts::non_empty());
  cli.add_option("--clock", a.clock, "real time: tick on the loop's own deadlines (loop) or on each of the "
                                     "device's samples (device: udp); overrides [device] clock")
      ->check(CLI::IsMember({"loop", "device"}));
  cli.add_flag("--fast", a.fast, "stepped clock: run the haptic session as fast as possible");
  cli.add_flag("--no-realtime", a.no_rt, "do not ask for SCHED_FIFO / mlockall");
}

void add_transport_options(CLI::App& cli, Args& a) {
  transport::TransportOptions& tr = a.tr;
  cli.add_option("--name", tr.server_name, "server name: key expressions hapticloth/<name>/... (default: default)")
      ->check(opts::satisfies(transport::server_name_error, "NAME"));
  a.zenoh_config = cli.add_option("--zenoh-config", tr.zenoh_config, "zenoh JSON5 config file (default: peer, listen tcp/127.0.0.1:7447, no scouting)")
      ->check(opts::non_empty());
  a.zenoh_listen = cli.add_option("--zenoh-listen", tr.zenoh_listen, "zenoh endpoint to listen on without a config file (default tcp/127.0.0.1:7447)")
      ->check(opts::satisfies(transport::zenoh_endpoint_error, "ENDPOINT"));
  cli.add_flag("--no-zenoh", a.no_zenoh, "do not publish over zenoh");
  cli.add_option("--lcm-url", tr.lcm_url, "also publish on this LCM provider (e.g. udpm://239.255.76.67:7667?ttl=0)")
      ->check(opts::satisfies(transport::lcm_url_error, "URL"));
  cli.add_option("--lcm-log", tr.lcm_log, "LCM log of the run (every message); default out/<scene>.lcm")
      ->check(opts::writable_file());
  cli.add_flag("--no-lcm-log", a.no_lcm_log, "do not write the LCM log");
  cli.add_option("--foxglove", tr.foxglove,
                 "Foxglove live view (WebSocket) on HOST:PORT; without a value 127.0.0.1:8765 (off by default)")
      ->expected(0, 1)
      ->default_str("127.0.0.1:8765")
      ->check(CLI::Validator(
          [](std::string& s) -> std::string {
            std::string host;
            std::uint16_t port = 0;
            try {
              transport::parse_host_port(s, "", host, port);
            } catch (const std::invalid_argument& e) {
              return std::string(e.what()).substr(1);  // "--foxglove: <s>: why"
            }
            return "";
          },
          "HOST:PORT"));
  cli.add_option("--mcap", tr.mcap, "record the Foxglove channels to this new MCAP file")
      ->check(opts::new_file());
  cli.add_option("--cloth-rate", tr.cloth_rate, "Hz, cloth state messages (default 60)")
      ->check(opts::positive(1000.0, "Hz"));
  cli.add_option("--max-command-speed", tr.max_command_speed, "m/s, fastest injected fingertip trajectory (default 1)")
      ->check(opts::positive(100.0, "m/s"));
}

// --solver, --dt and --alpha over the scene's [integrator].
void override_integrator(const Args& a, app::Scene& scene) {
  if (!a.solver.empty()) scene.solver = a.solver;
  if (a.dt > 0) scene.integrator.dt = a.dt;
  if (a.alpha > 0) scene.integrator.alpha = a.alpha;
  scene.integrator.validate();
}

// --headless: steps the scene as fast as possible and prints the summary.
int run_headless_job(const Args& a, const app::Scene& scene) {
  const double duration = a.duration > 0 ? a.duration : scene.duration;
  const long steps = std::lround(duration / scene.integrator.dt);
  if (steps < 1) {
    std::cerr << "hapticloth-server: --duration " << duration << " s is shorter than one step (dt "
              << scene.integrator.dt << " s)\n";
    return 2;
  }
  // A signal while the model is built stops the run before its first step (the summary says so).
  app::RunSummary r = app::run_headless(scene, steps, &app::install_stop_signals());
  if (r.steps_asked_when_stopped)
    r.stopped = std::string("by ") + app::stop_signal_name() + " after " +
                std::to_string(r.steps) + " of " + std::to_string(r.steps_asked_when_stopped) + " steps";
  std::cout << (a.json ? r.to_json() + "\n" : r.to_text());
  return r.finite ? 0 : 1;
}

// The device options of the command line over the scene's [device]; false if there is no device.
bool choose_device(const Args& a, app::Scene& scene) {
  if (!a.device.empty()) {
    scene.device.driver = a.device;
    scene.has_device = true;
  }
  if (!scene.has_device) return false;
  if (!a.script.empty()) scene.device.script = a.script;
  if (!a.record.empty()) scene.device.record_path = a.record;
  if (!a.replay.empty()) scene.device.replay_path = a.replay;
  if (!a.udp_bind.empty()) scene.device.udp_bind = a.udp_bind;
  if (!a.clock.empty()) scene.haptics.device_clock = a.clock == "device";
  if (scene.haptics.device_clock && !devices::driver_paces_loop(scene.device.driver))
    throw app::ConfigError("clock \"device\" (--clock or the scene's [device] clock) needs a device "
                           "that streams on its own clock (udp), not " + scene.device.driver);
  if (a.no_rt) scene.haptics.try_realtime = false;
  const long triangles = static_cast<long>(scene.mesh.triangles.size());
  if (const std::string e = app::haptic_budget_error(triangles); !e.empty())
    throw app::ConfigError(scene.path + ": mesh: " + e);
  return true;
}

// The LCM log of the session: --lcm-log, none with --no-lcm-log, else out/<scene>.lcm.
std::string lcm_log_path(const Args& a, const app::Scene& scene) {
  if (a.no_lcm_log) return "";
  if (!a.tr.lcm_log.empty()) return a.tr.lcm_log;
  // By default every session leaves a real LCM log (file:// provider) that lcm-logplayer and
  // Python's lcm.EventLog read, in out/ under the current directory.
  std::error_code ec;
  std::filesystem::create_directories("out", ec);
  const std::string path = "out/" + scene.name + ".lcm";
  // The claim creates the file (and removes it again if the session never starts).
  if (!ec && ::access("out", W_OK | X_OK) == 0) return path;
  std::cerr << "hapticloth-server: cannot write " << path << "; running without the LCM log\n";
  return "";
}

// The session with the device: app::serve, stopped by SIGINT / SIGTERM.
int run_device_session(const Args& a, const app::Scene& scene) {
  app::ServeOptions so;
  so.transport = a.tr;
  so.transport.lcm_log = lcm_log_path(a, scene);
  // Held until the session ends: a second server given the same paths stops here.
  app::OutputClaims claims;
  claims.claim(so.transport.lcm_log, a.tr.lcm_log.empty() ? "the LCM log (--lcm-log)" : "--lcm-log");
  claims.claim(scene.device.record_path, a.record.empty() ? "[device] record" : "--record");
  for (std::size_t i = 0; i < scene.device.parts.size(); ++i)
    claims.claim(scene.device.parts[i].record_path, "[[device.part]] " + std::to_string(i) + " record");
  so.stop = &app::install_stop_signals();  // installed by main: its flag
  so.duration = a.duration;
  so.realtime = !a.fast;
  so.json = a.json;
  so.transport.zenoh = !a.no_zenoh;
  so.transport_required = a.zenoh_config->count() > 0 || a.zenoh_listen->count() > 0;
  const int rc = app::serve(scene, so, std::cout);  // throws before the session on bad set-up
  claims.keep();
  return rc;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App cli{"hapticloth-server: cloth simulation and haptic rendering server (HAPTEX model)"};
  Args a;
  add_run_options(cli, a);
  add_transport_options(cli, a);
  if (const int rc = opts::parse(cli, argc, argv); rc >= 0) return rc;

  // From here a signal stops the server (app/stop_signal.hpp).
  const std::atomic<bool>& stop = app::install_stop_signals();
  try {
    app::Scene scene = app::load_scene(a.scene_path);
    app::check_stop(&stop);
    override_integrator(a, scene);
    if (a.headless) return run_headless_job(a, scene);
    if (!choose_device(a, scene)) {
      std::cerr << "hapticloth-server: no device: give --device (" << a.known_drivers
                << ") or a [device] table in the scene, or run --headless\n";
      return 2;
    }
    return run_device_session(a, scene);
  } catch (const app::StoppedDuringSetUp& e) {
    std::cerr << "hapticloth-server: " << e.what() << "\n";
    return 0;
  } catch (const std::exception& e) {  // app::ConfigError (a bad scene or option) and the rest
    std::cerr << "hapticloth-server: " << e.what() << "\n";
    return 2;
  }
}
