// The session in Foxglove's terms: the Hub's LCM messages turned into Foxglove channels, served
// live over Foxglove's WebSocket protocol and/or written to an MCAP file, with the Foxglove SDK
// (the bridge crate's foxglove_sink.rs). `hapticloth-export` feeds it an LCM log instead, so a
// recording and an export of the same run hold the same channels.
//
//   /cloth       foxglove.SceneUpdate  the mesh (the scene's vertices and triangles) with
//                                      per-vertex colours: the eq. 4 strain of largest
//                                      magnitude, averaged over the vertex's triangles, on a
//                                      fixed +-1% cool-warm scale (hapticloth-render's)
//   /fingertips  foxglove.SceneUpdate  a sphere per fingertip proxy, an arrow for its force
//   /haptics     JSON                  per finger: force, position, proxy, contact, slip
//   /loop        JSON                  the haptic loop's statistics (loop_stats_t)
//   /events      foxglove.Log          the events (kind, text)
//   /tactile     JSON                  per finger: the vibration's RMS and last block, where on
//                                      the fabric (u, v), normal force (a tactile display only)
//   /tactile/pins foxglove.RawImage    the pin frames, side by side (mono8, mid-grey level)
//
// One message per LCM message: /cloth per cloth_state_t, /fingertips and /haptics per
// haptic_state_t batch (its last sample: about 100 Hz, fit for plots), /loop per
// loop_stats_t, /events per event_t, /tactile and /tactile/pins per tactile_state_t batch. Not thread-safe: the Hub's publisher thread calls it.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "cloth/element.hpp"
#include "transport/topics.hpp"

struct HfSink;
namespace hapticloth {
class cloth_topology_t;
class cloth_state_t;
}

namespace hapticloth::transport {

struct FoxgloveOptions {
  std::string live;           ///< HOST:PORT of the live view; empty: none
  std::string mcap;           ///< new MCAP file; empty: none
  std::string server_name = "default";
  double finger_radius = 0.008;  ///< m, the spheres on /fingertips
};

/// HOST:PORT into its parts; throws std::invalid_argument naming `what` if it is not one.
void parse_host_port(const std::string& s, const std::string& what, std::string& host, std::uint16_t& port);

/// The live view's address or the recording's file cannot be opened.
struct FoxgloveOpenError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class FoxgloveSink {
 public:
  enum Channel { Cloth, Fingertips, Haptics, Loop, Events, Tactile, TactilePins, kChannels };

  /// Throws FoxgloveOpenError naming the address or file that cannot be opened.
  explicit FoxgloveSink(const FoxgloveOptions& opt);
  ~FoxgloveSink();
  FoxgloveSink(const FoxgloveSink&) = delete;
  FoxgloveSink& operator=(const FoxgloveSink&) = delete;

  /// True if an LCM message of topic t feeds a channel someone takes now (the file, or a live
  /// client subscribed to it). The topology always: the mesh is needed for every cloth frame.
  bool wants(Topic t) const;
  /// The LCM message of topic t, logged at `utime` (us since the Unix epoch). A message that
  /// does not decode, or a cloth state before any topology, is counted, not published.
  void send(Topic t, const std::uint8_t* bytes, std::size_t len, std::int64_t utime);
  /// Stops the live view and finishes the file (its summary and footer). Throws
  /// std::runtime_error if the file cannot be finished. Also done (errors dropped) by the destructor.
  void close();

  std::uint16_t port() const { return port_; }
  std::uint64_t written(Channel c) const { return written_[c]; }
  std::uint64_t undecodable() const { return undecodable_; }
  std::uint64_t before_topology() const { return before_topology_; }
  static const char* channel_name(Channel c);

 private:
  template <class M>
  bool decode(const std::uint8_t* bytes, std::size_t len, M& m);
  void take_topology(const hapticloth::cloth_topology_t& t);
  void cloth(const std::uint8_t* bytes, std::size_t len, std::uint64_t ns);
  void haptics(const std::uint8_t* bytes, std::size_t len, std::uint64_t ns);
  void loop(const std::uint8_t* bytes, std::size_t len, std::uint64_t ns);
  void tactile(const std::uint8_t* bytes, std::size_t len, std::uint64_t ns);
  void event(const std::uint8_t* bytes, std::size_t len, std::uint64_t ns);
  void strain_colours(const std::vector<std::vector<float>>& x, std::size_t first,
                      const std::vector<cloth::ElementRest>& rest, const std::vector<bool>& degenerate);
  bool add_refined(const hapticloth::cloth_state_t& m);

  HfSink* sink_ = nullptr;
  FoxgloveOptions opt_;
  std::uint16_t port_ = 0;
  // The mesh, from the first topology (cloth_topology_t or scene_info_t).
  std::vector<std::uint32_t> triangles_;
  std::vector<cloth::ElementRest> rest_;
  std::vector<bool> degenerate_;
  std::size_t vertices_ = 0;
  // Scratch of one cloth frame: the global cloth, then the refined children in place of the
  // triangles they stand in for.
  std::vector<float> xyz_, rgba_, weight_;
  std::vector<std::uint32_t> tris_;
  std::vector<bool> hidden_, child_degenerate_;
  std::vector<cloth::ElementRest> child_rest_;
  std::vector<double> sum_;
  std::array<std::uint64_t, kChannels> written_{};
  std::uint64_t undecodable_ = 0, before_topology_ = 0;
};

}  // namespace hapticloth::transport
