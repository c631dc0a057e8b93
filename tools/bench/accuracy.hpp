// Work-precision and stability benchmarks of the cloth step and the haptic coupling
// (`hapticloth-bench accuracy`, `hapticloth-bench stability`). Both print one JSON object.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "app/scene_file.hpp"

namespace hapticloth::bench {

struct AccuracyOptions {
  bool quick = false;      ///< a reduced sweep (about a minute) for tests and a first look
  std::string source_dir;  ///< repository root (scenes and materials)
  bool verbose = true;     ///< progress on stderr
  /// fine_cloth(): the scene of the cloth (default tools/scenes/hanging_square_16k.toml)
  std::string fine_scene;
  /// accuracy(): local refinement under the fingertips in every run and the reference (default:
  /// the main job's haptics.refine)
  std::optional<haptics::Refine> refine;
};

/// Sweeps dt, alpha, solver and tolerance, and mesh resolution on three reference scenes
/// (the hanging square released from flat, a one-finger press, a two-finger pinch-lift) and
/// measures each run's error against a reference run (dt 0.05 ms, alpha 0.5, tight solve) and
/// its CPU time per simulated second. Marks the Pareto front of each scene.
nlohmann::json accuracy(const AccuracyOptions& opt);
/// The multirate path on the 15842-triangle hanging square against the same scene directly
/// coupled at 1 ms (tools/bench/fine_cloth.cpp).
nlohmann::json fine_cloth(const AccuracyOptions& opt);

struct StabilityOptions {
  bool quick = false;
  std::string source_dir;
  long random_steps = 100000;  ///< haptic ticks of the randomized-trajectory runs
  bool verbose = true;
  /// local refinement under the fingertips in every run (default: the main job's haptics.refine)
  std::optional<haptics::Refine> refine;
};

/// The stability stress map: dt x material stiffness (x1 .. x1000 the denim curves) x fingertip
/// speed (up to 2 m/s) x alpha, each cell a scripted stroke through the hanging square, plus
/// long randomized fingertip trajectories. Pass = no non-finite state, energy bounded,
/// penetration within tolerance, no abandoned (restored) step.
nlohmann::json stability(const StabilityOptions& opt);

struct LimitOptions {
  bool quick = false;
  std::string source_dir;
  bool verbose = true;
};

/// For the hanging square at about 1k, 4k and 16k triangles: our whole step (CHOLMOD and PCG)
/// against CHOLMOD's own analyze / factorize / solve of the same eq. 9 matrix (simplicial and
/// supernodal), the overhead ratio, and the factorization's flop count and fill.
nlohmann::json limit(const LimitOptions& opt);

struct FidelityOptions {
  bool quick = false;
  bool verbose = true;
  /// Instead: the hanging square pressed at these resolutions (quads a side), the last of them
  /// the reference (docs/contact.md, "The hanging square against a finer mesh").
  std::vector<int> square_press;
};

/// The touch against physics: the drum press against membrane theory per mesh, and the pinched
/// handkerchief against its weight (tools/bench/fidelity.cpp).
nlohmann::json fidelity(const FidelityOptions& opt);

struct LateTickOptions {
  std::string source_dir;
  unsigned seed = 1;
  bool verbose = true;
};

/// Press, stroke and pinch of the main job with ticks 1-20 ms late (tools/bench/late_ticks.cpp):
/// the energy the coupling gave beyond passivity and the force jumps, against the run on time.
nlohmann::json late_ticks(const LateTickOptions& opt);

struct TactileBenchOptions {
  std::string source_dir;
};

/// Strokes at 20, 50, 100 and 200 mm/s along the weft and the warp of every shipped material
/// through one fingertip's tactile channel (tools/bench/tactile.cpp): the vibration's peak
/// against v / lambda, its third-octave bands against the surface model's, and a still press.
nlohmann::json tactile(const TactileBenchOptions& opt);

/// The scene's cloth pinched at its middle by both fingertips (direct coupling, the scene's
/// solver) for `seconds` on the stepped clock: the global step's time with both in contact.
/// With `settle_s` > 0 the cloth is first brought to rest (settle_s of 20 ms steps) and pinched
/// across its surface at the vertex nearest its centroid; else the scene's start state is
/// pinched along z at the middle of its extent.
nlohmann::json pinch_step(const app::Scene& scene, double seconds, double settle_s = 0.0);
/// hapticloth-bench step --script: the scene's [device] script played on the stepped clock,
/// directly coupled at the haptic period, from the cloth brought to rest by the scene's preroll
/// (20 ms steps); the step's time by how many fingertips touch the cloth (tools/bench/script_step.cpp).
nlohmann::json script_step(const app::Scene& scene);

}  // namespace hapticloth::bench
