#include "transport/scene_messages.hpp"

#include <string>

#include "transport/topics.hpp"

namespace hapticloth::transport {

SceneMessages::SceneMessages(const TransportOptions& opt, const SceneInfo& scene)
    : scene_(scene), requested_(!opt.hold_until_session) {
  hapticloth::scene_info_t si;
  si.utime = wall_utime();
  si.server_name = opt.server_name;
  si.scene_name = scene.scene_name;
  si.material_name = scene.material_name;
  si.areal_density = scene.areal_density;
  si.device_name = scene.device.name;
  si.fingers = scene.device.fingers;
  for (int k = 0; k < 3; ++k) {
    si.workspace_min[k] = scene.device.workspace.min[k];
    si.workspace_max[k] = scene.device.workspace.max[k];
    si.device_origin[k] = scene.device_origin[k];
    for (int j = 0; j < 3; ++j) si.device_rotation[k][j] = scene.device_rotation(k, j);
  }
  si.max_force = scene.device.max_force;
  si.haptic_rate = scene.haptic_rate;
  si.cloth_rate = opt.cloth_rate;
  si.haptic_batch = opt.haptic_batch;
  si.max_command_speed = opt.max_command_speed;
  std::vector<std::string> topics;
  for (int t = 0; t < kTopics; ++t) topics.push_back(topic_name(static_cast<Topic>(t)));
  topics.push_back("trajectory");
  topics.push_back("scene_request");
  si.num_topics = static_cast<int32_t>(topics.size());
  for (const auto& t : topics) {
    si.topics.push_back(t);
    si.key_expressions.push_back(t == "scene_request" ? "" : key_expression(opt.server_name, t));
    si.lcm_channels.push_back(lcm_channel(t));
  }
  fill(scene, si.topology);
  encode(si, info_);
}

}  // namespace hapticloth::transport
