// Configuration of the state transports (zenoh, LCM, Foxglove), from the command line and the scene's
// [transport] table.
#pragma once

#include <string>

namespace hapticloth::transport {

struct TransportOptions {
  std::string server_name = "default";  ///< key expressions hapticloth/<server_name>/...
  bool zenoh = true;                    ///< publish over zenoh
  /// zenoh JSON5 config file; empty: peer mode, listen tcp/127.0.0.1:7447, no scouting.
  std::string zenoh_config;
  std::string zenoh_listen = "tcp/127.0.0.1:7447";
  std::string lcm_url;                  ///< extra LCM provider URL (udpm only inside a netns)
  std::string lcm_log;                  ///< file:// log path; empty: none
  std::string foxglove;                 ///< HOST:PORT of the Foxglove live view; empty: off
  std::string mcap;                     ///< MCAP recording (Foxglove channels); empty: none
  double finger_radius = 0.008;         ///< m, the fingertip spheres of the Foxglove view
  double cloth_rate = 60.0;             ///< Hz, cloth state messages
  double haptic_batch = 0.01;           ///< s, haptic samples per message (1 kHz batched)
  double max_command_speed = 1.0;       ///< m/s, fastest fingertip a trajectory command may ask
  /// The Hub is opened before the session (the server: before its preroll) and is there for
  /// clients only from Hub::session_started(): no scene published or answered, commands
  /// rejected, until then.
  bool hold_until_session = false;
};

// Checks of the options' values, each "" or why the value is wrong (without the option's name,
// which the caller adds). They are the checks the transports' constructors would make, run on
// the command line so that a bad value is exit 2 before the cloth settles.

/// A name that is one chunk of a key expression: non-empty, without / * $ ? #.
std::string server_name_error(const std::string& name);
/// PROTOCOL/ADDRESS[?METADATA][#CONFIG], and HOST:PORT for tcp and udp (zenoh's endpoint form).
std::string zenoh_endpoint_error(const std::string& endpoint);
/// PROVIDER://[NETWORK][?OPTIONS] with a provider LCM has (udpm, mpudpm, tcpq, file, memq).
std::string lcm_url_error(const std::string& url);

}  // namespace hapticloth::transport
