// How large a cloth this machine can hold, and how large a one the haptic loop can feel.
// - Memory: the model, state, matrix and solver take about kBytesPerTriangle (peak resident
//   memory with CHOLMOD, the larger of the two solvers), and a scene may use half of the
//   machine's physical memory. Checked when the scene is read, before the mesh is built.
// - The haptic budget: a device session renders from a cloth that must keep pace with the hand.
//   The multirate path is tested at global steps up to kLongestGlobalStepMs; the step of the
//   fastest solver (PCG) grows faster than the mesh (its iterations grow too): measured from
//   release, 9.06 ms at 31250 triangles and 58.7 ms at 125000, so about
//   kPcgRefStepMs (n / kPcgRefTriangles)^kPcgExponent. Checked before a device session settles.
#pragma once

#include <cstdint>
#include <string>

namespace hapticloth::app {

/// Peak resident memory per triangle: 542 MB at 125000 triangles with CHOLMOD, 357 MB with
/// PCG (`/usr/bin/time -f %M build/hapticloth-server --headless --duration 0.005` on the 16k
/// scene at resolution [250, 250]).
constexpr double kBytesPerTriangle = 4.4e3;
/// The PCG step against the mesh: the median of the first 50 steps from release of the 16k
/// scene at resolutions [125, 125] and [250, 250] (`build/hapticloth-server --scene S
/// --headless --duration 0.05 --json`, ms_per_step_median: 9.06 and 58.7 ms, 10.5 and 19.9
/// iterations; 23.6 ms at 62658 triangles).
constexpr double kPcgRefTriangles = 31250.0, kPcgRefStepMs = 9.06, kPcgExponent = 1.35;
/// The estimated PCG step of a mesh, ms.
double pcg_step_ms(long triangles);
/// The longest global step the multirate path is tested at (25 Hz: test_session
/// MultirateKeepsForceContinuousAt25Hz).
constexpr double kLongestGlobalStepMs = 40.0;

/// Physical memory of this machine, bytes.
std::uint64_t physical_memory();
/// The largest mesh a scene may have on this machine (half its memory).
long max_triangles_for_memory();
/// The largest mesh whose estimated PCG step fits the haptic budget.
long max_triangles_for_haptics();

/// "" if `triangles` fit in memory, else why not (the figures the limit comes from).
std::string memory_limit_error(long triangles);
/// "" if `triangles` fit the haptic budget, else why not.
std::string haptic_budget_error(long triangles);

}  // namespace hapticloth::app
