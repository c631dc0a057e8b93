// The simulated Kawabata (KES-F) tests: a tensile test along weft or warp and the shear test,
// run on a meshed specimen with the cloth solver, reported against the material's own curve
// and, optionally, against measured points.
#pragma once

#include <string>
#include <vector>

#include "cloth/material.hpp"

namespace hapticloth::app {

enum class KesTest { Weft, Warp, Shear };
KesTest parse_kes_test(const std::string& name);  ///< "weft" | "warp" | "shear", else throws
const char* to_string(KesTest t);

struct KesOptions {
  int load_steps = 30;          ///< quasi-static increments per loading branch
  double max_strain = 0.0;      ///< tensile: largest strain; 0 = the curve's max_strain
  double max_shear_deg = 8.0;   ///< shear: sweep -max..+max degrees (KES-F: 8)
  double lateral_tension = 9.80665;  ///< shear: N/m held across the specimen (KES-F: 10 gf/cm)
  int cells_per_cm = 2;         ///< mesh resolution of the specimen
  bool free_edges = false;      ///< shear: leave the side edges free (as on the tester) instead
                                ///< of guiding them along the affine shear
};

/// One equilibrium state of the test.
struct KesPoint {
  double strain = 0.0;    ///< tensile: clamp displacement / gauge length; shear: eps_uv (eq. 4)
  double angle = 0.0;     ///< shear: clamp shear angle, rad (atan of offset / gap); tensile: 0
  double stress = 0.0;    ///< N/m: force per unit clamp width (docs/kes.md for shear)
  double clamp_force = 0.0;  ///< N/m: raw clamp force per unit width along the loading direction
  double material = 0.0;  ///< N/m: the material law at `strain`
  int newton_iterations = 0;
  double residual = 0.0;  ///< N: largest net force on a free vertex
};

struct KesMeasured {
  std::vector<double> strain, stress;
};

struct KesResult {
  KesTest test = KesTest::Weft;
  std::vector<KesPoint> points;  ///< sorted by strain
  double max_stress = 0.0;       ///< N/m, largest |material stress| over the test
  double material_rms = 0.0, material_max = 0.0;  ///< N/m, simulated vs material law
  double measured_rms = -1.0, measured_max = -1.0;  ///< N/m, simulated vs measured (-1: none)
  double measured_max_stress = 0.0;
  int triangles = 0;
  bool converged = true;
};

/// Runs the test. Throws std::runtime_error if a load step does not reach equilibrium.
KesResult run_kes(const cloth::Material& m, KesTest test, const KesOptions& opt);

/// Adds the comparison with measured points (interpolating the simulated curve at the
/// measured strains inside the simulated range).
void compare_measured(KesResult& r, const KesMeasured& measured);

/// Reads the points of one test from a measured CSV (`test,strain,stress`, `#` comments).
/// Throws app::ConfigError naming the file and line on bad input.
KesMeasured load_measured(const std::string& path, KesTest test);

std::string kes_to_json(const KesResult& r);
std::string kes_to_text(const KesResult& r);
std::string kes_to_csv(const KesResult& r);

}  // namespace hapticloth::app
