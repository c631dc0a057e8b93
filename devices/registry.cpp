#include "registry.hpp"

#include <map>
#include <stdexcept>

#include "composite/composite_device.hpp"
#include "mock/mock_device.hpp"
#include "replay/replay_device.hpp"
#ifdef HAPTICLOTH_HAVE_UDP
#include "udp/udp_device.hpp"
#endif
#ifdef HAPTICLOTH_HAVE_REMOTE
#include "remote/remote_device.hpp"
#endif

namespace hapticloth::devices {

namespace {
struct Driver {
  DeviceFactory make;
  bool paces_loop;  ///< as the driver's Device::paces_loop
};

const std::map<std::string, Driver>& registry() {
  static const std::map<std::string, Driver> r = {
      {"composite", {make_composite_device, false}},
      {"mock", {make_mock_device, false}},
      {"replay", {make_replay_device, false}},
#ifdef HAPTICLOTH_HAVE_UDP
      {"udp", {make_udp_device, true}},
#endif
#ifdef HAPTICLOTH_HAVE_REMOTE
      {"remote", {make_remote_device, false}},
#endif
  };
  return r;
}
}  // namespace

std::vector<std::string> device_names() {
  std::vector<std::string> n;
  for (const auto& [k, v] : registry()) n.push_back(k);
  return n;
}

std::unique_ptr<Device> make_device(const DeviceOptions& opt) {
  const auto& r = registry();
  const auto it = r.find(opt.driver);
  if (it == r.end()) {
    std::string known;
    for (const auto& [k, v] : r) known += (known.empty() ? "" : ", ") + k;
    throw std::invalid_argument("unknown device '" + opt.driver + "' (" + known + ")");
  }
  return it->second.make(opt);
}

bool driver_paces_loop(const std::string& driver) {
  const auto it = registry().find(driver);
  return it != registry().end() && it->second.paces_loop;
}

}  // namespace hapticloth::devices
