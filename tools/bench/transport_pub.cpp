// Publisher side of the transport benchmark (hapticloth-bench-transport, in the Python package,
// runs it and measures at the subscriber). The mesh state of the ~1000-triangle square:
//   --mode hub  through the real Hub (mailbox, publisher thread, zenoh/LCM) at --rate Hz
//   --mode raw  encode + put in a tight loop on the same zenoh/LCM wrappers (throughput)
#include <chrono>
#include <cmath>
#include <iostream>
#include <optional>
#include <thread>

#include "cli_checks.hpp"

#include "cloth/material.hpp"
#include "cloth/mesh.hpp"
#include "transport/hub.hpp"
#include "transport/lcm_bus.hpp"
#include "transport/zenoh_session.hpp"

namespace {

using namespace hapticloth;
using Clock = std::chrono::steady_clock;

struct Options {
  std::string mode = "hub", listen = "tcp/127.0.0.1:7447", lcm_url, name = "bench";
  double rate = 1000.0, duration = 5.0;
  int n = 22;
};

// The command line; an exit code when it is wrong or asked for help.
std::optional<int> parse_options(int argc, char** argv, Options& o) {
  CLI::App cli{"hapticloth-bench-transport-pub: publishes the cloth state for the transport benchmark"};
  cli.add_option("--mode", o.mode, "hub or raw")->check(CLI::IsMember({"hub", "raw"}));
  cli.add_option("--zenoh-listen", o.listen, "zenoh endpoint (empty: no zenoh)");
  cli.add_option("--lcm-url", o.lcm_url, "LCM provider (empty: none)");
  cli.add_option("--name", o.name, "server name in the key expressions");
  cli.add_option("--rate", o.rate, "Hz of cloth states (hub mode)")->check(opts::positive(1e5, "Hz"));
  cli.add_option("--duration", o.duration, "seconds to publish")->check(opts::positive(3600.0, "s"));
  cli.add_option("--grid", o.n, "quads per side (22: 968 triangles)")->check(CLI::Range(1, 400));
  if (const int rc = opts::parse(cli, argc, argv); rc >= 0) return rc;
  return std::nullopt;
}

// --mode hub: the mesh's states through the real Hub at --rate; the states it published.
std::uint64_t publish_through_hub(const Options& o, const cloth::Mesh& mesh, Clock::time_point end) {
  cloth::Material mat;
  mat.name = "bench";
  transport::SceneInfo info;
  transport::set_cloth(info, mesh, mat);
  info.scene_name = "bench";
  haptics::ClothSnapshot snap;
  snap.resize(static_cast<int>(mesh.positions.size()));
  for (std::size_t i = 0; i < mesh.positions.size(); ++i) snap.x[i] = mesh.positions[i];
  transport::TransportOptions t;
  t.server_name = o.name;
  t.zenoh = !o.listen.empty();
  t.zenoh_listen = o.listen;
  t.lcm_url = o.lcm_url;
  t.cloth_rate = o.rate;
  auto hub = transport::make_hub(t, info);
  const auto period = std::chrono::duration<double>(1.0 / o.rate);
  auto next = Clock::now();
  for (std::uint64_t k = 0; Clock::now() < end; ++k) {
    snap.time = k / o.rate;
    snap.step = k;
    snap.x[0].z() = 1e-3 * std::sin(snap.time);
    hub->on_sim_step(snap);
    next += std::chrono::duration_cast<Clock::duration>(period);
    std::this_thread::sleep_until(next);
  }
  hub->flush();
  return hub->stats().published[static_cast<int>(transport::Topic::Cloth)];
}

// --mode raw: encode and put in a tight loop on the zenoh and LCM wrappers; the states sent.
std::uint64_t publish_raw(const Options& o, const cloth::Mesh& mesh, Clock::time_point end) {
  std::unique_ptr<transport::ZenohSession> zs;
  std::unique_ptr<transport::ZenohPublisher> zp;
  std::unique_ptr<transport::LcmBus> lcm;
  if (!o.listen.empty()) {
    zs = std::make_unique<transport::ZenohSession>("", o.listen);
    zp = std::make_unique<transport::ZenohPublisher>(*zs, transport::key_expression(o.name, "cloth"));
  }
  if (!o.lcm_url.empty()) lcm = std::make_unique<transport::LcmBus>(o.lcm_url);
  hapticloth::cloth_state_t m{};  // every count 0, the refinement's too
  m.num_vertices = static_cast<int32_t>(mesh.positions.size());
  m.positions.assign(m.num_vertices, std::vector<float>(3));
  for (int i = 0; i < m.num_vertices; ++i)
    for (int k = 0; k < 3; ++k) m.positions[i][k] = static_cast<float>(mesh.positions[i][k]);
  std::vector<std::uint8_t> buf;
  // Wait (bounded by the duration) for a subscriber before the clock starts.
  while (zp && !zp->matching() && Clock::now() < end) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  std::uint64_t sent = 0;
  for (; Clock::now() < end; ++sent) {
    m.utime = transport::wall_utime();
    m.step = static_cast<int64_t>(sent);
    transport::encode(m, buf);
    if (zp) zp->put(buf.data(), buf.size());
    if (lcm) {
      lcm->publish("HAPTICLOTH_CLOTH", buf.data(), buf.size());
      // udpm drops at the receiver without pacing; 20 us keeps the socket buffer drained.
      std::this_thread::sleep_for(std::chrono::microseconds(20));
    }
  }
  return sent;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  if (const std::optional<int> rc = parse_options(argc, argv, o)) return *rc;
  cloth::GridSpec g;
  g.nx = g.ny = o.n;
  const cloth::Mesh mesh = cloth::make_grid(g);
  const Clock::time_point end =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(o.duration));
  const std::uint64_t sent = o.mode == "hub" ? publish_through_hub(o, mesh, end) : publish_raw(o, mesh, end);
  std::cout << "{\"sent\": " << sent << ", \"triangles\": " << mesh.triangles.size()
            << ", \"vertices\": " << mesh.positions.size() << "}" << std::endl;
  return 0;
}
