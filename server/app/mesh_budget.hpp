// How large a cloth this machine can hold, and how large a one the haptic loop can feel.
// - Memory: the model, state, matrix and solver take about kBytesPerTriangle (peak resident
//   memory with CHOLMOD, the larger of the two solvers), and a scene may use half of the
//   machine's physical memory. Checked when the scene is read, before the mesh is built.
// - The haptic budget: a device session renders from a cloth that must keep pace with the hand.
//   The multirate path is tested at global steps up to kLongestGlobalStepMs; the step of the
//   fastest solver (PCG) grows faster than the mesh (its iterations grow too), so it is taken
//   as kPcgRefStepMs (n / kPcgRefTriangles)^kPcgExponent, fitted to the step measured from
//   release at two mesh sizes (docs/performance.md, 'The mesh budget'). Checked before a
//   device session settles.
#pragma once

#include <cstdint>
#include <string>

namespace hapticloth::app {

/// Peak resident memory per triangle, with CHOLMOD, the larger of the two solvers
/// (docs/performance.md, 'The mesh budget').
constexpr double kBytesPerTriangle = 4.4e3;
/// The PCG step against the mesh: a power law through the median steps from release of the 16k
/// scene at two resolutions (docs/performance.md, 'The mesh budget').
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
