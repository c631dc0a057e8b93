// The topics a Hub publishes and their names on each transport (see hub.hpp for the table).
#pragma once

#include <string>

namespace hapticloth::transport {

enum class Topic : int { Topology, Cloth, Haptics, Stats, Events, Scene, Tactile };
inline constexpr int kTopics = 7;
const char* topic_name(Topic t);
/// hapticloth/<server>/<topic>
std::string key_expression(const std::string& server, const std::string& topic);
/// HAPTICLOTH_<TOPIC>
std::string lcm_channel(const std::string& topic);

}  // namespace hapticloth::transport
