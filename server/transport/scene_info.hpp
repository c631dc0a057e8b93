// What the scene queryable answers (hapticloth/<server>/scene) and what cloth_topology_t
// carries: fixed for a run.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "hal/device.hpp"

namespace hapticloth::cloth {
struct Mesh;
struct Material;
}  // namespace hapticloth::cloth

namespace hapticloth::transport {

struct SceneInfo {
  std::string scene_name;
  std::string material_name;
  double areal_density = 0.0;                          ///< kg/m^2
  /// m: the surface's period along the weft and the warp (cloth::Surface; 0: none given)
  double weft_period = 0.0, warp_period = 0.0;
  std::vector<std::array<int, 3>> triangles;
  std::vector<Eigen::Vector3d> rest_positions;         ///< m, scene frame
  std::vector<std::array<std::array<double, 2>, 3>> weave_uv;  ///< m, per triangle corner
  devices::DeviceInfo device;
  /// p_scene = device_rotation * p_device + device_origin
  Eigen::Matrix3d device_rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d device_origin = Eigen::Vector3d::Zero();
  double haptic_rate = 1000.0;                         ///< Hz
};

/// The mesh and material parts of a SceneInfo (device and mapping left as given).
void set_cloth(SceneInfo& info, const cloth::Mesh& mesh, const cloth::Material& material);

}  // namespace hapticloth::transport
