#include "transport/topics.hpp"

#include <algorithm>
#include <cctype>

namespace hapticloth::transport {

namespace {
constexpr const char* kTopicNames[kTopics] = {"topology", "cloth", "haptics", "stats", "events", "scene", "tactile"};
}  // namespace

const char* topic_name(Topic t) { return kTopicNames[static_cast<int>(t)]; }

std::string key_expression(const std::string& server, const std::string& topic) {
  return "hapticloth/" + server + "/" + topic;
}

std::string lcm_channel(const std::string& topic) {
  std::string c = "HAPTICLOTH_" + topic;
  std::transform(c.begin(), c.end(), c.begin(), [](unsigned char ch) { return std::toupper(ch); });
  return c;
}

}  // namespace hapticloth::transport
