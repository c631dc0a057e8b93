// A run as the renderer sees it: the cloth mesh (fixed), the cloth states and the haptic
// samples, read from an LCM log written by hapticloth-server (--lcm-log) or collected from the
// zenoh topics (zenoh_source.hpp).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace hapticloth::render {

using Vec3f = Eigen::Vector3f;

/// The cloth mesh of a run (cloth_topology_t), plus what scene_info_t adds.
struct Scene {
  std::string name;                                           ///< scene name ("" if unknown)
  std::vector<std::array<int, 3>> triangles;                  ///< CCW seen from the rest normal
  std::vector<Vec3f> rest_positions;                          ///< m, scene frame
  std::vector<std::array<std::array<float, 2>, 3>> weave_uv;  ///< m, per triangle corner (u weft, v warp)
  double haptic_rate = 1000.0;                                ///< Hz
};

/// The refined children under the fingertips in one cloth_state_t (paper 4.2.2): a mesh of
/// their own, drawn in place of the global triangles in `region`. Empty when none.
struct RefinedFrame {
  Scene mesh;                    ///< triangles and weave coordinates (no rest positions)
  std::vector<Vec3f> positions;  ///< m, scene frame, one per mesh vertex
  std::vector<int> region;       ///< global triangles (Scene::triangles) the children stand in for
  bool empty() const { return mesh.triangles.empty(); }
};

/// One cloth_state_t.
struct ClothFrame {
  double time = 0.0;        ///< s, session loop clock
  std::int64_t step = 0;
  std::vector<Vec3f> positions;  ///< m, scene frame, one per Scene vertex
  RefinedFrame refined;
};

/// One finger at one haptic tick (scene frame).
struct FingerSample {
  Vec3f position = Vec3f::Zero();  ///< m, fingertip centre (the device position in the scene)
  Vec3f proxy = Vec3f::Zero();     ///< m, god-object proxy
  Vec3f force = Vec3f::Zero();     ///< N, on the user's fingertip
  bool contact = false;
};

/// One haptic tick (one sample of haptic_state_t).
struct HapticTick {
  double time = 0.0;  ///< s, session loop clock
  std::int64_t tick = 0;
  std::vector<FingerSample> fingers;
};

struct Recording {
  bool has_topology = false;
  Scene scene;
  std::vector<ClothFrame> frames;    ///< in time order (after finish())
  std::vector<HapticTick> haptics;   ///< in time order (after finish())
  std::size_t dropped = 0;           ///< cloth states that do not fit the mesh (vertex count, refined region)

  /// Index of the frame whose time is nearest `time`. `frames` must not be empty.
  std::size_t frame_near(double time) const;
  /// The last haptic tick at or before `time` (the first one if all are later); nullptr if
  /// there are none.
  const HapticTick* haptics_at(double time) const;
};

/// Bad or unsuitable input (an unreadable log, no topology): the message says which and why.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Adds one LCM-encoded message to `rec`, recognised by its type fingerprint (the channel name
/// does not matter): cloth_topology_t, scene_info_t, cloth_state_t, haptic_state_t. Returns
/// false for bytes that are none of these (other types, corrupt data).
bool add_message(Recording& rec, const std::uint8_t* data, std::size_t len);

/// Sorts frames and haptic ticks by time and drops cloth states that do not fit the mesh (their
/// vertex count, or a refined region naming a triangle it lacks; counted in `dropped`). Call
/// once all messages are in.
void finish(Recording& rec);

/// Reads an LCM log written by hapticloth-server --lcm-log. Throws InputError
/// "<path>: cannot open as an LCM log" or "<path>: no cloth_topology_t message (was the log
/// written by hapticloth-server?)".
Recording read_lcm_log(const std::string& path);

}  // namespace hapticloth::render
