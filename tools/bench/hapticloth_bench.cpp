// hapticloth-bench: benchmarks that print machine-readable results.
//   hapticloth-bench step --scene FILE [--solver cholmod|pcg] [--dt S] [--alpha A] [--steps N] [--threads 1|2]
//                         [--pcg-preconditioner ssor|block-jacobi] [--pcg-omega W] [--matrix-refresh R]
//                         [--simd baseline|avx2|avx512]
//                         [--pinch [--settle S]] --json
//   hapticloth-bench haptic [--scene FILE] [--duration S] [--no-tactile] --json
//   hapticloth-bench haptic --subscribers N [--duration S] [--cloth-rate HZ] --json
//   hapticloth-bench timer [--ticks N] [--priority P] --json
//   hapticloth-bench udp [options of hapticloth-bench-udp] --json
//   hapticloth-bench transport [options of hapticloth-bench-transport] --json
//   hapticloth-bench accuracy [--quick] --json [--plot OUT.png]
//   hapticloth-bench stability [--quick] [--random-steps N] --json [--plot OUT.png]
//   hapticloth-bench limit [--quick] --json
//   hapticloth-bench fidelity [--quick] [--square-press 22,45,178] --json
//   hapticloth-bench late-ticks [--seed N] --json
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <sstream>
#include <vector>

#include <unistd.h>

#include "cli_checks.hpp"

#include "accuracy.hpp"
#include "hal/platform_timer.hpp"
#include "app/run_summary.hpp"
#include "app/scene_file.hpp"
#include "app/serve.hpp"
#include "app/toml_file.hpp"

namespace {

// Benchmarks that live in their own programs (built beside this one) are run through here so
// that every benchmark is `hapticloth-bench NAME`.
int exec_sibling(const char* program, int argc, char** argv) {
  namespace fs = std::filesystem;
  const fs::path self = fs::read_symlink("/proc/self/exe");
  const std::string path = (self.parent_path() / program).string();
  std::vector<char*> args;
  args.push_back(const_cast<char*>(path.c_str()));
  for (int i = 2; i < argc; ++i) args.push_back(argv[i]);
  args.push_back(nullptr);
  ::execv(path.c_str(), args.data());
  std::cerr << "hapticloth-bench: cannot run " << path << " (is it built?)\n";
  return 2;
}

// Plots a benchmark's JSON with tools/bench/plot_bench.py (matplotlib in .venv).
int plot(const std::string& json_path, const std::string& png) {
  const std::string top = HAPTICLOTH_SOURCE_DIR;
  const std::string cmd = "'" + top + "/.venv/bin/python' '" + top + "/tools/bench/plot_bench.py' '" +
                          json_path + "' '" + png + "'";
  const int rc = std::system(cmd.c_str());
  if (rc != 0) std::cerr << "hapticloth-bench: plotting failed (" << cmd << ")\n";
  return rc == 0 ? 0 : 1;
}

// Prints the result and writes it beside the plot when one is asked for.
int finish(const nlohmann::json& j, bool json, const std::string& png) {
  const std::string text = j.dump(json ? -1 : 1);
  std::cout << text << "\n";
  if (png.empty()) return 0;
  const std::string jp = png.substr(0, png.rfind('.')) + ".json";
  std::ofstream(jp) << j.dump() << "\n";
  return plot(jp, png);
}

}  // namespace

int main(int argc, char** argv) {
  using namespace hapticloth;
  if (argc >= 2 && std::string(argv[1]) == "udp") return exec_sibling("hapticloth-bench-udp", argc, argv);
  if (argc >= 2 && std::string(argv[1]) == "haptic" &&
      std::any_of(argv + 2, argv + argc, [](const char* a) {
        const std::string s(a);
        return s.rfind("--subscribers", 0) == 0 || s.rfind("--foxglove-clients", 0) == 0;
      })) {
    // With subscribers: the server and its zenoh and LCM subscribers (or Foxglove's WebSocket
    // clients) run as processes inside a network namespace (Python:
    // clients/python/hapticloth/bench_subscribers.py).
    const std::string py = std::string(HAPTICLOTH_SOURCE_DIR) + "/.venv/bin/python";
    std::vector<char*> args{const_cast<char*>(py.c_str()), const_cast<char*>("-m"),
                            const_cast<char*>("hapticloth.bench_subscribers")};
    for (int i = 2; i < argc; ++i) args.push_back(argv[i]);
    args.push_back(nullptr);
    ::execv(py.c_str(), args.data());
    std::cerr << "hapticloth-bench: cannot run " << py << " (run tools/setup)\n";
    return 2;
  }
  if (argc >= 2 && std::string(argv[1]) == "transport") {
    // The transport benchmark's subscriber side is Python (the client package in .venv).
    const std::string py = std::string(HAPTICLOTH_SOURCE_DIR) + "/.venv/bin/hapticloth-bench-transport";
    std::vector<char*> args{const_cast<char*>(py.c_str())};
    for (int i = 2; i < argc; ++i) args.push_back(argv[i]);
    args.push_back(nullptr);
    ::execv(py.c_str(), args.data());
    std::cerr << "hapticloth-bench: cannot run " << py << " (run tools/setup)\n";
    return 2;
  }

  // The benchmark's name comes first: say which option or name is wrong (CLI11 would only say
  // that a subcommand is required).
  const std::vector<std::string> names{"step", "haptic", "timer", "accuracy", "stability", "limit", "fidelity",
                                        "late-ticks", "tactile"};
  if (argc >= 2 && std::string(argv[1]) != "-h" && std::string(argv[1]) != "--help" &&
      std::find(names.begin(), names.end(), argv[1]) == names.end()) {
    std::cerr << "hapticloth-bench: " << (argv[1][0] == '-' ? "unknown option " : "unknown benchmark ")
              << argv[1] << " (the benchmark comes first: step, haptic, timer, accuracy, stability, limit, "
              << "fidelity, late-ticks, tactile, udp, transport; --help)\n";
    return 2;
  }
  CLI::App cli{"hapticloth-bench: benchmarks with machine-readable output"};
  cli.require_subcommand(1);

  auto* step = cli.add_subcommand("step", "time the cloth step of a scene, headless");
  std::string scene_path, solver;
  double dt = -1, alpha = -1, tol = -1;
  long steps = 2000;
  bool json = false;
  step->add_option("--scene", scene_path, "scene file (TOML)")->required();
  step->add_option("--solver", solver, "pcg, cholmod or cholmod-supernodal (default: the scene's)");
  step->add_option("--dt", dt, "time step, s (default: the scene's)")->check(opts::positive(1.0, "s"));
  step->add_option("--alpha", alpha, "alpha in [0.5, 1] (default: the scene's)")->check(opts::number_in(0.5, 1.0));
  step->add_option("--pcg-tolerance", tol, "relative residual of the PCG solve")
      ->check(opts::number_in(0.0, 1.0, true));
  step->add_option("--steps", steps, "number of steps from the rest state")->check(CLI::Range(1L, 100000000L));
  std::string preconditioner, simd;
  step->add_option("--pcg-preconditioner", preconditioner, "ssor or block-jacobi (default: the scene's)")
      ->check(CLI::IsMember({"ssor", "block-jacobi"}));
  double omega = 0;
  step->add_option("--pcg-omega", omega, "SSOR's relaxation factor in [1, 2) (default: the scene's)")
      ->check(CLI::Range(1.0, 1.999));
  double refresh = -1;
  step->add_option("--matrix-refresh", refresh,
                   "an element's change that forms its blocks anew, in [0, 1); 0 forms the matrix whole every "
                   "step (default: the scene's)")
      ->check(CLI::Range(0.0, 0.999));
  int threads = 0;
  step->add_option("--threads", threads, "threads of the element assembly, 1 or 2 (default: the scene's)")
      ->check(CLI::Range(1, 2));
  step->add_option("--simd", simd, "instruction level of the element pass: baseline, avx2 or avx512 "
                   "(default: the widest this CPU runs); a level the CPU lacks is refused")
      ->check(CLI::IsMember({"baseline", "avx2", "avx512"}));
  step->add_flag("--json", json, "one JSON object on stdout");
  bool pinch = false;
  auto* pinch_flag = step->add_flag("--pinch", pinch, "both fingertips pinch the cloth's middle (direct coupling, "
                                                       "stepped clock, --steps haptic ticks)");
  double settle_s = 0.0;
  step->add_option("--settle", settle_s,
                   "--pinch: bring the cloth to rest first with S s of 20 ms steps (as the haptic scenes' "
                   "preroll does) and pinch it across its surface (default 0: pinch the scene's start state)")
      ->check(opts::number_in(0.0, 60.0))
      ->needs(pinch_flag);
  bool script = false;
  auto* script_flag = step->add_flag("--script", script,
                                     "play the scene's [device] script from the cloth at rest (its preroll), directly "
                                     "coupled on the stepped clock: the step's time by fingertips in contact");
  script_flag->excludes(pinch_flag);
  std::string refine;  // step --script / --pinch and haptic: overrides haptics.refine
  step->add_option("--refine", refine,
                   "--script, --pinch: local refinement under the fingertips, auto, on or off (default: the "
                   "scene's haptics.refine)")
      ->check(CLI::IsMember({"auto", "on", "off"}));

  auto* haptic = cli.add_subcommand(
      "haptic", "the 1 kHz haptic loop in real time with the mock device and the global "
                "simulation on the other thread: period error, compute time, missed deadlines");
  std::string haptic_scene = std::string(HAPTICLOTH_SOURCE_DIR) + "/tools/scenes/hanging_square.toml";
  double haptic_duration = 10.0;
  haptic->add_option("--scene", haptic_scene, "scene with a [device] table (default: the main job's)");
  haptic->add_option("--duration", haptic_duration, "s in real time (default 10)")
      ->check(opts::positive(3600.0, "s"));
  haptic->add_flag("--json", json, "one JSON object on stdout");
  bool no_tactile = false;
  haptic->add_flag("--no-tactile", no_tactile,
                   "without the device's tactile display (the scene's [device.tactile]): the loop's "
                   "figures with tactile rendering off, to compare");
  haptic->add_option("--refine", refine,
                     "local refinement under the fingertips, auto, on or off (default: the scene's haptics.refine)")
      ->check(CLI::IsMember({"auto", "on", "off"}));
  int subscribers_help = 0;  // handled before parsing (main's first lines): listed for --help
  haptic->add_option("--subscribers", subscribers_help,
                     "N subscribers (half zenoh, half LCM) at a 120 Hz cloth rate: the period error "
                     "against none, median of 3 off/on pairs, beside the platform timer");
  haptic->add_option("--foxglove-clients", subscribers_help,
                     "N Foxglove WebSocket clients on the live view (on in every run), as --subscribers");

  auto* timer = cli.add_subcommand(
      "timer", "the platform's wake-up latency at the haptic thread's scheduling, cyclictest-style "
               "(1 kHz absolute deadlines, no spin): the floor under every real-time figure");
  long timer_ticks = 10000;
  int timer_priority = 80;
  timer->add_option("--ticks", timer_ticks, "wake-ups to measure (default 10000: 10 s)")
      ->check(CLI::Range(1L, 100000000L));
  timer->add_option("--priority", timer_priority, "SCHED_FIFO priority (default 80, the haptic thread's)")
      ->check(CLI::Range(1, 99));
  timer->add_flag("--json", json, "one JSON object on stdout");

  auto* acc = cli.add_subcommand(
      "accuracy", "work-precision: error against a reference run vs CPU time per simulated "
                  "second, over dt, alpha, solver, tolerance and mesh resolution");
  bool quick = false;
  std::string png;
  acc->add_flag("--quick", quick, "a reduced sweep (about a minute)");
  bool fine_cloth = false;
  acc->add_flag("--fine-cloth", fine_cloth, "only the multirate path on the 15842-triangle square "
                                            "against direct coupling at 1 ms (several minutes)");
  std::string fine_scene;
  acc->add_option("--fine-scene", fine_scene, "--fine-cloth: another cloth (a scene file of the "
                                              "same 0.5 m square, e.g. tools/scenes/hanging_square_4k.toml)");
  acc->add_flag("--json", json, "one JSON object on one line");
  acc->add_option("--plot", png, "also write this PNG (and the JSON beside it)")->check(opts::writable_file());

  auto* stab = cli.add_subcommand(
      "stability", "stability stress map: dt x stiffness x fingertip speed x alpha, and long "
                   "randomized fingertip trajectories");
  long random_steps = 100000;
  stab->add_flag("--quick", quick, "a reduced map");
  stab->add_option("--random-steps", random_steps, "haptic ticks of each randomized run (default 1e5)")
      ->check(CLI::Range(1L, 100000000L));
  stab->add_flag("--json", json, "one JSON object on one line");
  stab->add_option("--plot", png, "also write this PNG (and the JSON beside it)")->check(opts::writable_file());

  auto* lim = cli.add_subcommand(
      "limit", "our whole step against CHOLMOD's own factorize and solve of the same matrix, "
               "per mesh size, with the factorization's flop count");
  lim->add_flag("--quick", quick, "a few steps per size");
  lim->add_flag("--json", json, "one JSON object on one line");
  auto* fid = cli.add_subcommand(
      "fidelity", "the touch against physics: drum press vs membrane theory per mesh, pinched "
                  "handkerchief vs its weight (BENCHMARKS.md, Force fidelity)");
  fid->add_flag("--quick", quick, "two meshes and one pinch");
  fid->add_flag("--json", json, "one JSON object on one line");
  std::vector<int> square_quads;
  fid->add_option("--square-press", square_quads,
                  "instead: the hanging square pressed on these meshes (quads a side, the last the "
                  "reference), e.g. 22,45,178")
      ->delimiter(',')
      ->check(CLI::Range(4, 400));
  auto* late = cli.add_subcommand(
      "late-ticks", "press, stroke and pinch with ticks 1-20 ms late: energy given beyond "
                    "passivity and force jumps, against the same run on time");
  unsigned late_seed = 1;
  late->add_option("--seed", late_seed, "seed of the late moments (default 1)");
  late->add_flag("--json", json, "one JSON object on one line");
  auto* tac = cli.add_subcommand(
      "tactile", "strokes over every shipped material's weave through the tactile channel: peak "
                 "against v / lambda, third-octave bands against the surface model (docs/tactile.md)");
  tac->add_flag("--json", json, "one JSON object on one line");
  // Listed for --help; they run in their own programs (exec_sibling above, before parsing).
  cli.add_subcommand("udp", "rig -> server -> rig round trip of the UDP device on loopback, beside "
                            "the platform's timer (options: hapticloth-bench udp --help)");
  cli.add_subcommand("transport", "publish-to-receive latency of zenoh and LCM on loopback "
                                  "(options: hapticloth-bench transport --help)");
  if (const int rc = opts::parse(cli, argc, argv); rc >= 0) return rc;

  // The benchmarks that return one JSON result, and whether --plot applies to them.
  struct JsonBenchmark {
    const CLI::App* command;
    std::function<nlohmann::json()> run;
    bool plot;
  };
  const std::string source_dir = HAPTICLOTH_SOURCE_DIR;
  const JsonBenchmark json_benchmarks[] = {
      {acc, [&] {
         const bench::AccuracyOptions o{.quick = quick, .source_dir = source_dir, .fine_scene = fine_scene};
         return fine_cloth ? bench::fine_cloth(o) : bench::accuracy(o);
       }, !fine_cloth},
      {stab, [&] { return bench::stability({.quick = quick, .source_dir = source_dir, .random_steps = random_steps}); },
       true},
      {lim, [&] { return bench::limit({.quick = quick, .source_dir = source_dir}); }, false},
      {fid, [&] { return bench::fidelity({.quick = quick, .square_press = square_quads}); }, false},
      {late, [&] { return bench::late_ticks({.source_dir = source_dir, .seed = late_seed}); }, false},
      {tac, [&] { return bench::tactile({.source_dir = source_dir}); }, false},
  };

  try {
    for (const JsonBenchmark& b : json_benchmarks)
      if (*b.command) return finish(b.run(), json, b.plot ? png : "");
    // --refine: as the scene key haptics.refine would set it (and refused where the key is).
    const auto apply_refine = [&](app::Scene& sc) {
      if (refine.empty()) return;
      sc.haptics.coupling.refine = refine == "on" ? haptics::Refine::On : refine == "off" ? haptics::Refine::Off
                                                                                          : haptics::Refine::Auto;
      if (sc.haptics.coupling.refine == haptics::Refine::On && sc.rendering == "multirate" &&
          sc.multirate_model == haptics::LocalModel::Patch)
        throw std::invalid_argument("--refine on: scene '" + sc.name + "' renders with the patch model, which "
                                    "renders from its own subdivided patch");
    };
    if (*haptic) {
      app::Scene scene = app::load_scene(haptic_scene);
      if (!scene.has_device) throw std::runtime_error(haptic_scene + ": no [device] table");
      apply_refine(scene);
      if (no_tactile) scene.device.tactile = devices::TactileCapability{};
      app::ServeOptions so;
      so.duration = haptic_duration;
      so.realtime = true;
      so.json = true;
      std::ostringstream out;
      const int rc = app::serve(scene, so, out);
      // The session report, and beside it the platform's timer over as many ticks, measured
      // right after in the same invocation, with the loop's excess over it.
      nlohmann::json j = nlohmann::json::parse(out.str());
      const devices::TimerFigures platform = devices::measure_timer(std::lround(haptic_duration * 1000.0));
      j["platform_timer"] = platform.to_json();
      const double loop_p99 = j["period_error_us"]["p99"].get<double>();
      j["period_error_p99_excess_us"] = loop_p99 - platform.p99_us;
      std::cout << j.dump() << "\n";
      return rc;
    }
    if (*timer) {
      std::cout << devices::measure_timer(timer_ticks, 1e-3, timer_priority).to_json().dump(json ? -1 : 1) << "\n";
      return 0;
    }
    app::Scene scene = app::load_scene(scene_path);
    if (!solver.empty()) scene.solver = solver;
    if (dt > 0) scene.integrator.dt = dt;
    if (alpha > 0) scene.integrator.alpha = alpha;
    if (tol > 0) scene.pcg.tolerance = tol;
    if (!preconditioner.empty())
      scene.pcg.preconditioner = preconditioner == "ssor" ? cloth::PcgPreconditioner::Ssor : cloth::PcgPreconditioner::BlockJacobi;
    if (omega > 0) scene.pcg.ssor_omega = omega;
    if (threads > 0) scene.integrator.assembly_threads = threads;
    if (refresh >= 0) scene.integrator.matrix_refresh = refresh;
    if (!simd.empty()) {
      const cloth::SimdLevel level = *cloth::parse_simd_level(simd);
      if (!cloth::runs_here(level)) {
        std::cerr << "hapticloth-bench: --simd " << simd << ": this CPU lacks its instructions (it runs "
                  << cloth::to_string(cloth::best_level()) << ")\n";
        return 2;
      }
      scene.integrator.simd = level;
    }
    scene.integrator.validate();
    apply_refine(scene);
    if (script) {
      std::cout << bench::script_step(scene).dump(json ? -1 : 1) << "\n";
      return 0;
    }
    if (pinch) {
      std::cout << bench::pinch_step(scene, steps / scene.haptics.haptic_rate, settle_s).dump(json ? -1 : 1) << "\n";
      return 0;
    }
    const app::RunSummary r = app::run_headless(scene, steps);
    std::cout << (json ? r.to_json() + "\n" : r.to_text());
    return r.finite ? 0 : 1;
  } catch (const std::exception& e) {
    std::cerr << "hapticloth-bench: " << e.what() << "\n";
    return 2;
  }
}
