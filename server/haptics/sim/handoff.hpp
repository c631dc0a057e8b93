// What the simulation thread hands the haptic thread and back (through TripleBuffers).
// All storage is sized once at set-up; copying a snapshot into a slot never allocates.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "hal/device.hpp"
#include "hal/rt_handoff.hpp"

namespace hapticloth::haptics {

using Vec3 = Eigen::Vector3d;
inline constexpr int kMaxFingers = devices::kMaxFingers;
using devices::TripleBuffer;

/// A fingertip proxy after a global step (direct coupling: solved with the cloth).
struct ProxyResult {
  bool valid = false;            ///< the step had a device sample for this finger
  Vec3 proxy = Vec3::Zero();     ///< proxy sphere centre, m
  Vec3 target = Vec3::Zero();    ///< the device fingertip the coupling pulled towards, m
  Vec3 target_velocity = Vec3::Zero();  ///< its velocity, m/s
  Vec3 force = Vec3::Zero();     ///< force on the user's finger, N: minus the cloth's contact forces
  Vec3 normal = Vec3::Zero();    ///< direction of the summed normal contact forces (towards the finger)
  Vec3 contact = Vec3::Zero();   ///< normal-force-weighted centre of the contacts, m
  int triangle = -1;             ///< triangle of the strongest contact
  double bary[3] = {0, 0, 0};
  int points = 0;                ///< cloth samples in contact
  bool in_contact = false;
  bool slipping = false;         ///< every contact slides (gross slip)
  double normal_force = 0.0;     ///< sum of the contacts' normal force magnitudes, N
  double friction_force = 0.0;   ///< sum of the contacts' tangential force magnitudes, N
  double penetration = 0.0;      ///< deepest cloth point inside the sphere, m
  double patch_radius = 0.0;     ///< m: the farthest pressing contact from the contact's centre, across the normal
  /// Material coordinates (u weft, v warp), m, of the cloth's point nearest the proxy's
  /// centre: where on the fabric's surface the fingertip presses (tactile rendering).
  double weave_u = 0.0, weave_v = 0.0;
  /// d(u, v)/dx on the cloth there (tactile::weave_map), and the cloth's velocity there (m/s):
  /// how the fingertip's slip moves it over the fabric until the next step (tactile::WeaveTracker).
  Eigen::Matrix<double, 2, 3> weave_map = Eigen::Matrix<double, 2, 3>::Zero();
  Vec3 surface_velocity = Vec3::Zero();
  /// N/m: the coupling spring the step solved with (the scene's, or with local refinement the
  /// scene's in series with the compliance the global mesh lacks: LocalRefinement).
  double coupling_stiffness = 0.0;
};

/// Global cloth state at one simulation step, for the haptic loop.
struct ClothSnapshot {
  double time = -1.0;         ///< loop clock of the step (s); < 0: none yet
  std::uint64_t step = 0;
  std::vector<Vec3> x, v;     ///< vertex positions (m), velocities (m/s)
  std::array<bool, kMaxFingers> near{};  ///< the fingertip is within reach of the cloth
  std::array<ProxyResult, kMaxFingers> proxy{};  ///< direct coupling: the step's proxies
  /// The multirate path's local model (cloth::Integrator::proxy_response): R[p * kMaxFingers + q],
  /// how finger p's force moves with finger q's fingertip until the next global step.
  bool has_response = false;
  std::array<Eigen::Matrix3d, kMaxFingers * kMaxFingers> response{};
  /// The patch model's candidates (multirate path, local model "patch"): per finger, the global
  /// triangles with a corner within reach of the fingertip at the step (SimWorker::
  /// mark_patch_candidates), in index order, found on the simulation thread so that a patch
  /// built on the haptic thread scans these and not the whole mesh. The first near_count[f]
  /// entries of near_triangles[f] hold them.
  std::array<std::vector<int>, kMaxFingers> near_triangles;
  std::array<int, kMaxFingers> near_count{};

  /// Storage for `vertices` vertices and `candidates` patch candidates per finger.
  void resize(int vertices, int candidates = 0) {
    x.assign(vertices, Vec3::Zero());
    v.assign(vertices, Vec3::Zero());
    for (auto& t : near_triangles) t.assign(candidates, 0);
  }
  /// Copy that keeps this snapshot's storage (no allocation when sizes match).
  void assign(const ClothSnapshot& o) {
    time = o.time;
    step = o.step;
    std::copy(o.x.begin(), o.x.end(), x.begin());
    std::copy(o.v.begin(), o.v.end(), v.begin());
    near = o.near;
    proxy = o.proxy;
    has_response = o.has_response;
    response = o.response;
    near_count = o.near_count;
    for (std::size_t f = 0; f < near_triangles.size(); ++f)
      std::copy(o.near_triangles[f].begin(), o.near_triangles[f].begin() + o.near_count[f],
                near_triangles[f].begin());
  }
};

/// One finger as the haptic loop saw it on its latest tick (scene frame).
struct FingerReport {
  Vec3 position = Vec3::Zero();  ///< fingertip centre (device position mapped to the scene), m
  Vec3 proxy = Vec3::Zero();     ///< god-object position, m
  Vec3 force = Vec3::Zero();     ///< force on the user's finger, N (the cloth gets -force)
  Vec3 spring = Vec3::Zero();    ///< the coupling spring's part of it (its damper's left out), N
  Vec3 normal = Vec3::Zero();    ///< shaded contact normal, pointing towards the finger
  Vec3 contact = Vec3::Zero();   ///< contact point on the cloth, m
  int triangle = -1;             ///< contact triangle, -1 if none
  double bary[3] = {0, 0, 0};
  double stiffness = 0.0;        ///< N/m of the contact spring (for the implicit coupling)
  /// The device has a fresh sample of this finger (its first one arrived and the watchdog has
  /// not tripped since). An absent finger touches nothing and is rendered no force.
  bool present = false;
  bool in_contact = false;
  bool slipping = false;
  Vec3 velocity = Vec3::Zero();      ///< fingertip velocity, m/s (scene frame)
  std::uint64_t impacts = 0;         ///< contact onsets so far (4.3.2: the sim applies each once)
};

struct HapticReport {
  double time = -1.0;
  std::uint64_t tick = 0;
  std::array<FingerReport, kMaxFingers> finger{};
};

}  // namespace hapticloth::haptics
