// Scene files (TOML): mesh, material, pins, physics and integrator settings.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "cloth/integrator.hpp"
#include "hal/options.hpp"
#include "haptics/session.hpp"
#include "cloth/mesh.hpp"
#include "cloth/solver.hpp"

namespace hapticloth::app {

/// The solvers a scene (integrator.solver) or --solver names.
inline const std::vector<std::string> kSolvers = {"pcg", "cholmod", "cholmod-supernodal"};
/// integrator.dt and --dt: from 1 us (a thousandth of the haptic period; shorter steps round
/// the velocity update away) to 1 s.
constexpr double kMinDt = 1e-6, kMaxDt = 1.0;

struct Scene {
  std::string path;
  std::string name;
  std::string material_path;
  cloth::Mesh mesh;
  cloth::Material material;
  std::vector<int> pins;
  cloth::IntegratorConfig integrator;
  std::string solver = "pcg";
  cloth::PcgOptions pcg;
  double duration = 10.0;  ///< s, default run length of the main job

  /// [device]: the haptic device (driver chosen by name; see devices/registry.hpp).
  bool has_device = false;
  devices::DeviceOptions device;
  /// [haptics]: the 1 kHz loop, fingertips, coupling and safety gate.
  haptics::SessionConfig haptics;
  double preroll = 0.0;  ///< s simulated (as fast as possible) before the device session starts
  /// How the simulation and the haptic loop share the fingertips (haptics.rendering): "direct"
  /// (a global step per haptic tick), "multirate" (the haptic loop renders from a local model
  /// between longer global steps), or "auto" (multirate when the global step does not fit in
  /// the haptic period, measured at start-up).
  std::string rendering = "auto";
  /// The multirate path's local model (haptics.multirate_model).
  haptics::LocalModel multirate_model = haptics::LocalModel::Response;
  /// What the loader has to say about the file that is not an error (an old key read as its
  /// new name), one line each; the server prints them.
  std::vector<std::string> notes;
};

/// Loads a scene; relative paths inside it are resolved against the scene file's folder.
/// Throws ConfigError naming file, line and key on bad input.
Scene load_scene(const std::string& path);

/// The model and integrator a scene describes.
cloth::ClothModel build_model(const Scene& scene);
std::unique_ptr<cloth::Integrator> make_integrator(const Scene& scene,
                                                   const cloth::ClothModel& model);

}  // namespace hapticloth::app
