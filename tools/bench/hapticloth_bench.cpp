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
#include <optional>
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

using namespace hapticloth;

// Runs `program` (its path first) with this invocation's arguments after the benchmark's name,
// so that every benchmark is `hapticloth-bench NAME`; returns only if it cannot, saying why.
int exec_program(std::vector<std::string> program, int argc, char** argv, const char* hint) {
  for (int i = 2; i < argc; ++i) program.emplace_back(argv[i]);
  std::vector<char*> args;
  for (std::string& a : program) args.push_back(a.data());
  args.push_back(nullptr);
  ::execv(args[0], args.data());
  std::cerr << "hapticloth-bench: cannot run " << program[0] << " (" << hint << ")\n";
  return 2;
}

// A benchmark built as its own program beside this one.
int exec_sibling(const char* program, int argc, char** argv) {
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe");
  return exec_program({(self.parent_path() / program).string()}, argc, argv, "is it built?");
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

// The benchmarks that run in another program: the UDP round trip (C++, beside this one), the
// haptic loop with subscribers or Foxglove clients in a network namespace
// (clients/python/hapticloth/bench_subscribers.py) and the transport latency (Python).
std::optional<int> run_elsewhere(int argc, char** argv) {
  const std::string name = argc >= 2 ? argv[1] : "";
  const std::string venv = std::string(HAPTICLOTH_SOURCE_DIR) + "/.venv/bin/";
  const bool with_peers = std::any_of(argv + std::min(argc, 2), argv + argc, [](const char* a) {
    const std::string s(a);
    return s.rfind("--subscribers", 0) == 0 || s.rfind("--foxglove-clients", 0) == 0;
  });
  if (name == "udp") return exec_sibling("hapticloth-bench-udp", argc, argv);
  if (name == "haptic" && with_peers)
    return exec_program({venv + "python", "-m", "hapticloth.bench_subscribers"}, argc, argv, "run tools/setup");
  if (name == "transport") return exec_program({venv + "hapticloth-bench-transport"}, argc, argv, "run tools/setup");
  return std::nullopt;
}

// The benchmark's name comes first: say which option or name is wrong (CLI11 would only say
// that a subcommand is required).
std::optional<int> refuse_unknown_benchmark(int argc, char** argv) {
  const std::vector<std::string> names{"step", "haptic", "timer", "accuracy", "stability", "limit", "fidelity",
                                        "late-ticks", "tactile"};
  if (argc < 2 || std::string(argv[1]) == "-h" || std::string(argv[1]) == "--help" ||
      std::find(names.begin(), names.end(), argv[1]) != names.end())
    return std::nullopt;
  std::cerr << "hapticloth-bench: " << (argv[1][0] == '-' ? "unknown option " : "unknown benchmark ") << argv[1]
            << " (the benchmark comes first: step, haptic, timer, accuracy, stability, limit, "
            << "fidelity, late-ticks, tactile, udp, transport; --help)\n";
  return 2;
}

// What `step` changes in its scene.
struct StepOptions {
  std::string scene_path, solver, preconditioner, simd;
  double dt = -1, alpha = -1, tol = -1, omega = 0, refresh = -1, settle_s = 0.0;
  long steps = 2000;
  int threads = 0;
  bool pinch = false, script = false;
};

// Every option of every benchmark: CLI11 writes them here.
struct Options {
  bool json = false, quick = false;
  std::string png, refine;  // --plot; --refine overrides haptics.refine
  StepOptions step;
  std::string haptic_scene = std::string(HAPTICLOTH_SOURCE_DIR) + "/tools/scenes/hanging_square.toml";
  double haptic_duration = 10.0;
  bool no_tactile = false;
  long timer_ticks = 10000;
  int timer_priority = 80;
  bool fine_cloth = false;
  std::string fine_scene;
  long random_steps = 100000;
  std::vector<int> square_quads;
  unsigned late_seed = 1;
};

// The benchmarks, as CLI11 subcommands (each one is true once parsed if it was named).
struct Commands {
  CLI::App *step, *haptic, *timer, *accuracy, *stability, *limit, *fidelity, *late_ticks, *tactile;
};

// --refine auto|on|off on benchmark `b`: what it refines, and what it is without the option.
void add_refine(CLI::App* b, Options& o, const std::string& what, const std::string& otherwise) {
  b->add_option("--refine", o.refine, what + ", auto, on or off (default: " + otherwise + ")")
      ->check(CLI::IsMember({"auto", "on", "off"}));
}

CLI::App* add_step(CLI::App& cli, Options& o) {
  StepOptions& s = o.step;
  auto* step = cli.add_subcommand("step", "time the cloth step of a scene, headless");
  step->add_option("--scene", s.scene_path, "scene file (TOML)")->required();
  step->add_option("--solver", s.solver, "pcg, cholmod or cholmod-supernodal (default: the scene's)");
  step->add_option("--dt", s.dt, "time step, s (default: the scene's)")->check(opts::positive(1.0, "s"));
  step->add_option("--alpha", s.alpha, "alpha in [0.5, 1] (default: the scene's)")->check(opts::number_in(0.5, 1.0));
  step->add_option("--pcg-tolerance", s.tol, "relative residual of the PCG solve")
      ->check(opts::number_in(0.0, 1.0, true));
  step->add_option("--steps", s.steps, "number of steps from the rest state")->check(CLI::Range(1L, 100000000L));
  step->add_option("--pcg-preconditioner", s.preconditioner, "ssor or block-jacobi (default: the scene's)")
      ->check(CLI::IsMember({"ssor", "block-jacobi"}));
  step->add_option("--pcg-omega", s.omega, "SSOR's relaxation factor in [1, 2) (default: the scene's)")
      ->check(CLI::Range(1.0, 1.999));
  step->add_option("--matrix-refresh", s.refresh,
                   "an element's change that forms its blocks anew, in [0, 1); 0 forms the matrix whole every "
                   "step (default: the scene's)")
      ->check(CLI::Range(0.0, 0.999));
  step->add_option("--threads", s.threads, "threads of the element assembly, 1 or 2 (default: the scene's)")
      ->check(CLI::Range(1, 2));
  step->add_option("--simd", s.simd, "instruction level of the element pass: baseline, avx2 or avx512 "
                   "(default: the widest this CPU runs); a level the CPU lacks is refused")
      ->check(CLI::IsMember({"baseline", "avx2", "avx512"}));
  step->add_flag("--json", o.json, "one JSON object on stdout");
  auto* pinch_flag = step->add_flag("--pinch", s.pinch, "both fingertips pinch the cloth's middle (direct "
                                                        "coupling, stepped clock, --steps haptic ticks)");
  step->add_option("--settle", s.settle_s,
                   "--pinch: bring the cloth to rest first with S s of 20 ms steps (as the haptic scenes' "
                   "preroll does) and pinch it across its surface (default 0: pinch the scene's start state)")
      ->check(opts::number_in(0.0, 60.0))
      ->needs(pinch_flag);
  auto* script_flag = step->add_flag("--script", s.script,
                                     "play the scene's [device] script from the cloth at rest (its preroll), directly "
                                     "coupled on the stepped clock: the step's time by fingertips in contact");
  script_flag->excludes(pinch_flag);
  add_refine(step, o, "--script, --pinch: local refinement under the fingertips", "the scene's haptics.refine");
  return step;
}

CLI::App* add_haptic(CLI::App& cli, Options& o) {
  auto* haptic = cli.add_subcommand(
      "haptic", "the 1 kHz haptic loop in real time with the mock device and the global "
                "simulation on the other thread: period error, compute time, missed deadlines");
  haptic->add_option("--scene", o.haptic_scene, "scene with a [device] table (default: the main job's)");
  haptic->add_option("--duration", o.haptic_duration, "s in real time (default 10)")
      ->check(opts::positive(3600.0, "s"));
  haptic->add_flag("--json", o.json, "one JSON object on stdout");
  haptic->add_flag("--no-tactile", o.no_tactile,
                   "without the device's tactile display (the scene's [device.tactile]): the loop's "
                   "figures with tactile rendering off, to compare");
  add_refine(haptic, o, "local refinement under the fingertips", "the scene's haptics.refine");
  static int listed_only = 0;  // run_elsewhere takes these before parsing: listed for --help
  haptic->add_option("--subscribers", listed_only,
                     "N subscribers (half zenoh, half LCM) at a 120 Hz cloth rate: the period error "
                     "against none, median of 3 off/on pairs, beside the platform timer");
  haptic->add_option("--foxglove-clients", listed_only,
                     "N Foxglove WebSocket clients on the live view (on in every run), as --subscribers");
  return haptic;
}

CLI::App* add_timer(CLI::App& cli, Options& o) {
  auto* timer = cli.add_subcommand(
      "timer", "the platform's wake-up latency at the haptic thread's scheduling, cyclictest-style "
               "(1 kHz absolute deadlines, no spin): the floor under every real-time figure");
  timer->add_option("--ticks", o.timer_ticks, "wake-ups to measure (default 10000: 10 s)")
      ->check(CLI::Range(1L, 100000000L));
  timer->add_option("--priority", o.timer_priority, "SCHED_FIFO priority (default 80, the haptic thread's)")
      ->check(CLI::Range(1, 99));
  timer->add_flag("--json", o.json, "one JSON object on stdout");
  return timer;
}

// A benchmark that prints one JSON result: its subcommand with --json, and --quick and --plot
// where it has them (quick: what --quick leaves out; empty: no --quick).
CLI::App* json_benchmark(CLI::App& cli, Options& o, const std::string& name, const std::string& what,
                         const std::string& quick = "", bool plot = false) {
  auto* b = cli.add_subcommand(name, what);
  if (!quick.empty()) b->add_flag("--quick", o.quick, quick);
  b->add_flag("--json", o.json, "one JSON object on one line");
  if (plot) b->add_option("--plot", o.png, "also write this PNG (and the JSON beside it)")->check(opts::writable_file());
  return b;
}

CLI::App* add_accuracy(CLI::App& cli, Options& o) {
  const std::string what = "work-precision: error against a reference run vs CPU time per simulated second, over "
                           "dt, alpha, solver, tolerance and mesh resolution";
  auto* acc = json_benchmark(cli, o, "accuracy", what, "a reduced sweep (about a minute)", true);
  acc->add_flag("--fine-cloth", o.fine_cloth, "only the multirate path on the 15842-triangle square "
                                              "against direct coupling at 1 ms (several minutes)");
  acc->add_option("--fine-scene", o.fine_scene, "--fine-cloth: another cloth (a scene file of the "
                                                "same 0.5 m square, e.g. tools/scenes/hanging_square_4k.toml)");
  add_refine(acc, o, "local refinement under the fingertips in every run and the reference",
             "the main job's haptics.refine");
  return acc;
}

CLI::App* add_stability(CLI::App& cli, Options& o) {
  auto* stab = json_benchmark(cli, o, "stability",
                              "stability stress map: dt x stiffness x fingertip speed x alpha, and long randomized "
                              "fingertip trajectories",
                              "a reduced map", true);
  stab->add_option("--random-steps", o.random_steps, "haptic ticks of each randomized run (default 1e5)")
      ->check(CLI::Range(1L, 100000000L));
  add_refine(stab, o, "local refinement under the fingertips in every run", "the main job's haptics.refine");
  return stab;
}

CLI::App* add_fidelity(CLI::App& cli, Options& o) {
  auto* fid = json_benchmark(cli, o, "fidelity",
                             "the touch against physics: drum press vs membrane theory per mesh, pinched "
                             "handkerchief vs its weight (BENCHMARKS.md, Force fidelity)",
                             "two meshes and one pinch");
  fid->add_option("--square-press", o.square_quads,
                  "instead: the hanging square pressed on these meshes (quads a side, the last the "
                  "reference), e.g. 22,45,178")
      ->delimiter(',')
      ->check(CLI::Range(4, 400));
  return fid;
}

CLI::App* add_late_ticks(CLI::App& cli, Options& o) {
  auto* late = json_benchmark(cli, o, "late-ticks",
                              "press, stroke and pinch with ticks 1-20 ms late: energy given beyond passivity and "
                              "force jumps, against the same run on time");
  late->add_option("--seed", o.late_seed, "seed of the late moments (default 1)");
  return late;
}

// Listed for --help; they run in their own programs (run_elsewhere, before parsing).
void add_elsewhere(CLI::App& cli) {
  cli.add_subcommand("udp", "rig -> server -> rig round trip of the UDP device on loopback, beside "
                            "the platform's timer (options: hapticloth-bench udp --help)");
  cli.add_subcommand("transport", "publish-to-receive latency of zenoh and LCM on loopback "
                                  "(options: hapticloth-bench transport --help)");
}

Commands add_commands(CLI::App& cli, Options& o) {
  Commands c{add_step(cli, o),      add_haptic(cli, o),     add_timer(cli, o),
             add_accuracy(cli, o),  add_stability(cli, o),
             json_benchmark(cli, o, "limit",
                            "our whole step against CHOLMOD's own factorize and solve of the same matrix, per mesh "
                            "size, with the factorization's flop count",
                            "a few steps per size"),
             add_fidelity(cli, o),  add_late_ticks(cli, o),
             json_benchmark(cli, o, "tactile",
                            "strokes over every shipped material's weave through the tactile channel: peak against "
                            "v / lambda, third-octave bands against the surface model (docs/tactile.md)")};
  add_elsewhere(cli);
  return c;
}

// --refine's value (checked by CLI11: auto, on or off), none if not given.
std::optional<haptics::Refine> parse_refine(const std::string& refine) {
  if (refine.empty()) return std::nullopt;
  return refine == "on" ? haptics::Refine::On : refine == "off" ? haptics::Refine::Off : haptics::Refine::Auto;
}

// The benchmarks that return one JSON result (and --plot where it applies), if one was named.
std::optional<int> run_json_benchmark(const Commands& c, const Options& o) {
  const std::string src = HAPTICLOTH_SOURCE_DIR;
  if (*c.accuracy) {
    const bench::AccuracyOptions a{.quick = o.quick, .source_dir = src, .fine_scene = o.fine_scene,
                                   .refine = parse_refine(o.refine)};
    return o.fine_cloth ? finish(bench::fine_cloth(a), o.json, "") : finish(bench::accuracy(a), o.json, o.png);
  }
  if (*c.stability)
    return finish(bench::stability({.quick = o.quick, .source_dir = src, .random_steps = o.random_steps,
                                     .refine = parse_refine(o.refine)}),
                  o.json, o.png);
  if (*c.limit) return finish(bench::limit({.quick = o.quick, .source_dir = src}), o.json, "");
  if (*c.fidelity) return finish(bench::fidelity({.quick = o.quick, .square_press = o.square_quads}), o.json, "");
  if (*c.late_ticks) return finish(bench::late_ticks({.source_dir = src, .seed = o.late_seed}), o.json, "");
  if (*c.tactile) return finish(bench::tactile({.source_dir = src}), o.json, "");
  return std::nullopt;
}

// --refine: as the scene key haptics.refine would set it (and refused where the key is).
void apply_refine(const std::string& refine, app::Scene& sc) {
  if (refine.empty()) return;
  sc.haptics.coupling.refine = *parse_refine(refine);
  if (sc.haptics.coupling.refine == haptics::Refine::On && sc.rendering == "multirate" &&
      sc.multirate_model == haptics::LocalModel::Patch)
    throw std::invalid_argument("--refine on: scene '" + sc.name + "' renders with the patch model, which "
                                "renders from its own subdivided patch");
}

// The session report, and beside it the platform's timer over as many ticks, measured right
// after in the same invocation, with the loop's excess over it.
int run_haptic(const Options& o) {
  app::Scene scene = app::load_scene(o.haptic_scene);
  if (!scene.has_device) throw std::runtime_error(o.haptic_scene + ": no [device] table");
  apply_refine(o.refine, scene);
  if (o.no_tactile) scene.device.tactile = devices::TactileCapability{};
  app::ServeOptions so;
  so.duration = o.haptic_duration;
  so.realtime = true;
  so.json = true;
  std::ostringstream out;
  const int rc = app::serve(scene, so, out);
  nlohmann::json j = nlohmann::json::parse(out.str());
  const devices::TimerFigures platform = devices::measure_timer(std::lround(o.haptic_duration * 1000.0));
  j["platform_timer"] = platform.to_json();
  j["period_error_p99_excess_us"] = j["period_error_us"]["p99"].get<double>() - platform.p99_us;
  std::cout << j.dump() << "\n";
  return rc;
}

int run_timer(const Options& o) {
  std::cout << devices::measure_timer(o.timer_ticks, 1e-3, o.timer_priority).to_json().dump(o.json ? -1 : 1) << "\n";
  return 0;
}

// The scene with step's overrides; false (after saying why) when --simd names a level this CPU
// lacks.
bool apply_step_options(const StepOptions& s, app::Scene& scene) {
  if (!s.solver.empty()) scene.solver = s.solver;
  if (s.dt > 0) scene.integrator.dt = s.dt;
  if (s.alpha > 0) scene.integrator.alpha = s.alpha;
  if (s.tol > 0) scene.pcg.tolerance = s.tol;
  if (!s.preconditioner.empty())
    scene.pcg.preconditioner =
        s.preconditioner == "ssor" ? cloth::PcgPreconditioner::Ssor : cloth::PcgPreconditioner::BlockJacobi;
  if (s.omega > 0) scene.pcg.ssor_omega = s.omega;
  if (s.threads > 0) scene.integrator.assembly_threads = s.threads;
  if (s.refresh >= 0) scene.integrator.matrix_refresh = s.refresh;
  if (!s.simd.empty()) {
    const cloth::SimdLevel level = *cloth::parse_simd_level(s.simd);
    if (!cloth::runs_here(level)) {
      std::cerr << "hapticloth-bench: --simd " << s.simd << ": this CPU lacks its instructions (it runs "
                << cloth::to_string(cloth::best_level()) << ")\n";
      return false;
    }
    scene.integrator.simd = level;
  }
  scene.integrator.validate();
  return true;
}

// `step`: the headless run, a scripted run (--script) or a pinch (--pinch).
int run_step(const Options& o) {
  const StepOptions& s = o.step;
  app::Scene scene = app::load_scene(s.scene_path);
  if (!apply_step_options(s, scene)) return 2;
  apply_refine(o.refine, scene);
  const int indent = o.json ? -1 : 1;
  if (s.script) {
    std::cout << bench::script_step(scene).dump(indent) << "\n";
    return 0;
  }
  if (s.pinch) {
    std::cout << bench::pinch_step(scene, s.steps / scene.haptics.haptic_rate, s.settle_s).dump(indent) << "\n";
    return 0;
  }
  const app::RunSummary r = app::run_headless(scene, s.steps);
  std::cout << (o.json ? r.to_json() + "\n" : r.to_text());
  return r.finite ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (const std::optional<int> rc = run_elsewhere(argc, argv)) return *rc;
  if (const std::optional<int> rc = refuse_unknown_benchmark(argc, argv)) return *rc;
  Options o;
  CLI::App cli{"hapticloth-bench: benchmarks with machine-readable output"};
  cli.require_subcommand(1);
  const Commands c = add_commands(cli, o);
  if (const int rc = opts::parse(cli, argc, argv); rc >= 0) return rc;
  try {
    if (const std::optional<int> rc = run_json_benchmark(c, o)) return *rc;
    if (*c.haptic) return run_haptic(o);
    if (*c.timer) return run_timer(o);
    return run_step(o);
  } catch (const std::exception& e) {
    std::cerr << "hapticloth-bench: " << e.what() << "\n";
    return 2;
  }
}
