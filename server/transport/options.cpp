#include "transport/options.hpp"

#include <algorithm>
#include <array>

namespace hapticloth::transport {

std::string server_name_error(const std::string& name) {
  if (name.empty()) return "must not be empty (it names the key expressions hapticloth/<name>/...)";
  if (name.find_first_of("/*$?#") != std::string::npos)
    return "'" + name + "' must not contain / * $ ? # (it is one chunk of the key expressions "
           "hapticloth/<name>/...)";
  return "";
}

std::string zenoh_endpoint_error(const std::string& endpoint) {
  const std::string form = " (PROTOCOL/ADDRESS, e.g. tcp/127.0.0.1:7447)";
  const auto slash = endpoint.find('/');
  if (slash == std::string::npos || slash == 0 || slash + 1 == endpoint.size())
    return "'" + endpoint + "' is not an endpoint" + form;
  const std::string protocol = endpoint.substr(0, slash);
  if (protocol.find_first_not_of("abcdefghijklmnopqrstuvwxyz0123456789-") != std::string::npos)
    return "'" + endpoint + "': '" + protocol + "' is not a protocol name" + form;
  if (protocol != "tcp" && protocol != "udp") return "";  // tls, quic, unixsock-stream...: zenoh checks
  std::string address = endpoint.substr(slash + 1);
  address = address.substr(0, address.find_first_of("?#"));
  const auto colon = address.rfind(':');
  const std::string port = colon == std::string::npos ? "" : address.substr(colon + 1);
  if (colon == std::string::npos || colon == 0 || port.empty() || port.size() > 5 ||
      port.find_first_not_of("0123456789") != std::string::npos || std::stol(port) > 65535)
    return "'" + endpoint + "': " + protocol + " needs HOST:PORT with a port up to 65535" + form;
  return "";
}

std::string lcm_url_error(const std::string& url) {
  static constexpr std::array<const char*, 5> kProviders = {"udpm", "mpudpm", "tcpq", "file", "memq"};
  const auto sep = url.find("://");
  const std::string provider = sep == std::string::npos ? "" : url.substr(0, sep);
  if (std::find(kProviders.begin(), kProviders.end(), provider) == kProviders.end())
    return "'" + url + "' is not an LCM URL (PROVIDER://NETWORK?OPTIONS with provider udpm, mpudpm, "
           "tcpq, file or memq, e.g. udpm://239.255.76.67:7667?ttl=0)";
  return "";
}

}  // namespace hapticloth::transport
