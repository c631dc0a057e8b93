// The Hub's wiring: what it publishes over zenoh (to a second zenoh session on loopback) and
// into its LCM log, the scene queryable, trajectory commands to the remote device, skipping
// topics nobody receives, and a real-time side that never allocates.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <mutex>
#include <set>
#include <thread>

#include <lcm/eventlog.h>

#include "remote/remote_device.hpp"
#include "support/alloc_counter.hpp"
#include "transport/hub.hpp"
#include "transport/zenoh_session.hpp"

namespace hapticloth::transport {
namespace {

using Clock = std::chrono::steady_clock;

// A port per test process run, so parallel ctest runs of other binaries do not collide.
int test_port() {
  static const int port = 17447 + static_cast<int>(::getpid() % 2000);
  return port;
}

SceneInfo small_scene() {
  SceneInfo s;
  s.scene_name = "test";
  s.material_name = "cotton";
  s.areal_density = 0.12;
  s.rest_positions = {{0, 0, 0}, {0.1, 0, 0}, {0, 0.1, 0}, {0.1, 0.1, 0}};
  s.triangles = {{0, 1, 2}, {1, 3, 2}};
  s.weave_uv = {{{{0, 0}, {0.1, 0}, {0, 0.1}}}, {{{0.1, 0}, {0.1, 0.1}, {0, 0.1}}}};
  s.device.name = "remote";
  s.device.fingers = 2;
  s.device_origin = Eigen::Vector3d(0, 0, 0.01);
  return s;
}

TransportOptions options(const std::string& log = "") {
  TransportOptions o;
  o.server_name = "test";
  o.zenoh_listen = "tcp/127.0.0.1:" + std::to_string(test_port());
  o.lcm_log = log;
  return o;
}

std::string client_config() {
  return "{ mode: \"peer\", listen: { endpoints: [] }, connect: { endpoints: [\"tcp/127.0.0.1:" +
         std::to_string(test_port()) +
         "\"] }, scouting: { multicast: { enabled: false }, gossip: { enabled: false } } }";
}

/// Collects decoded messages of one type from a zenoh key expression.
template <class M>
struct Collector {
  std::mutex mu;
  std::vector<M> got;
  std::unique_ptr<ZenohSubscriber> sub;
  Collector(const ZenohSession& s, const std::string& key) {
    sub = std::make_unique<ZenohSubscriber>(s, key, [this](const std::uint8_t* d, std::size_t n) {
      M m;
      if (decode(d, n, m)) {
        std::lock_guard<std::mutex> lock(mu);
        got.push_back(m);
      }
    });
  }
  std::size_t size() {
    std::lock_guard<std::mutex> lock(mu);
    return got.size();
  }
};

/// Polls `pred` every 10 ms for at most `seconds`.
template <class P>
bool eventually(P pred, double seconds = 5.0) {
  const auto end = Clock::now() + std::chrono::duration<double>(seconds);
  while (Clock::now() < end) {
    if (pred()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return pred();
}

haptics::ClothSnapshot snapshot(double t, std::uint64_t step) {
  haptics::ClothSnapshot s;
  s.resize(4);
  s.time = t;
  s.step = step;
  for (int i = 0; i < 4; ++i) s.x[i] = Eigen::Vector3d(i, 2.0 * i, t);
  return s;
}

TEST(Names, KeyExpressionsAndChannels) {
  EXPECT_EQ(key_expression("lab1", "cloth"), "hapticloth/lab1/cloth");
  EXPECT_EQ(lcm_channel("scene_request"), "HAPTICLOTH_SCENE_REQUEST");
  EXPECT_STREQ(topic_name(Topic::Haptics), "haptics");
}

// Opened before the preroll, the server's Hub is there for clients once its session starts:
// until then a command is rejected, saying why (the transports used to open after the preroll).
TEST(Hub, RejectsCommandsBeforeTheSession) {
  TransportOptions o = options();
  o.zenoh = false;
  o.hold_until_session = true;
  Hub hub(o, small_scene());
  hapticloth::trajectory_cmd_t m{};
  m.finger = 0;
  m.num_points = 1;
  m.times = {0.5};
  m.positions = {{0.0, 0.0, 0.0}};
  EXPECT_NE(hub.handle_command(m).find("the session has not started"), std::string::npos);
  hub.session_started();
  EXPECT_EQ(hub.handle_command(m).find("the session has not started"), std::string::npos);
  EXPECT_EQ(hub.stats().commands_rejected, 2u);  // the second: no remote device
}

TEST(Hub, RejectsABadServerName) {
  TransportOptions o = options();
  o.zenoh = false;
  o.server_name = "a/b";
  EXPECT_THROW(Hub(o, small_scene()), std::invalid_argument);
}

TEST(Hub, RejectsADeviceThatFailsValidation) {
  TransportOptions o = options();
  o.zenoh = false;
  SceneInfo s = small_scene();
  s.device.fingers = 1;  // a pinch needs two
  EXPECT_THROW(Hub(o, s), std::invalid_argument);
}

TEST(Hub, SkipsEverythingWithoutSubscribersOrLog) {
  Hub hub(options(), small_scene());
  hub.on_sim_step(snapshot(0.0, 1));
  haptics::HapticReport r;
  hub.on_haptic_tick(r, devices::DeviceState{}, devices::DeviceCommand{});
  hub.post_event("started", "");
  hub.flush();
  const HubStats s = hub.stats();
  for (int t = 0; t < kTopics; ++t) EXPECT_EQ(s.published[t], 0u) << topic_name(static_cast<Topic>(t));
  EXPECT_GE(s.skipped[static_cast<int>(Topic::Cloth)], 1u);
  EXPECT_GE(s.skipped[static_cast<int>(Topic::Haptics)], 1u);
  EXPECT_GE(s.skipped[static_cast<int>(Topic::Events)], 1u);
}

TEST(Hub, PublishesStateToAZenohSubscriber) {
  Hub hub(options(), small_scene());
  ZenohSession client(ZenohSession::Json5{client_config()});
  Collector<hapticloth::cloth_state_t> cloth(client, "hapticloth/test/cloth");
  Collector<hapticloth::haptic_state_t> haptic(client, "hapticloth/test/haptics");
  Collector<hapticloth::loop_stats_t> stats(client, "hapticloth/test/stats");
  haptics::RefinedRegions child;  // one child triangle standing in for global triangle 1
  child.version = 1;
  child.x = {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1e-3, 0, 0), Eigen::Vector3d(0, 1e-3, -2e-3)};
  child.triangles = {{0, 1, 2}};
  child.weave_uv = {{{{0.0, 0.0}, {1e-3, 0.0}, {0.0, 1e-3}}}};
  child.region = {1};
  hub.on_refined(child);

  // Feed the observer until the subscriptions have reached the Hub (bounded).
  std::uint64_t tick = 0;
  double t = 0.0;
  ASSERT_TRUE(eventually([&] {
    for (int k = 0; k < 10; ++k, ++tick) {
      t = tick * 1e-3;
      haptics::HapticReport r;
      r.time = t;
      r.tick = tick;
      r.finger[1].force = Eigen::Vector3d(0, 0, 1.5);
      r.finger[1].in_contact = true;
      devices::DeviceState st;
      st.finger[0].position = Eigen::Vector3d(0.01, 0.02, 0.03);
      hub.on_haptic_tick(r, st, devices::DeviceCommand{});
    }
    hub.on_sim_step(snapshot(t, tick));
    haptics::LoopStats ls;
    ls.ticks = tick;
    ls.period_error_us.add(3.0);
    hub.on_loop_stats(ls);
    hub.flush();
    return cloth.size() > 0 && haptic.size() > 0 && stats.size() > 0;
  }));
  {
    std::lock_guard<std::mutex> lock(cloth.mu);
    const auto& m = cloth.got.back();
    ASSERT_EQ(m.num_vertices, 4);
    EXPECT_FLOAT_EQ(m.positions[3][1], 6.0f);
    EXPECT_GT(m.utime, 0);
    ASSERT_EQ(m.num_refined_vertices, 3);
    ASSERT_EQ(m.num_refined_triangles, 1);
    ASSERT_EQ(m.num_refined_region, 1);
    EXPECT_FLOAT_EQ(m.refined_positions[2][2], -2e-3f);
    EXPECT_EQ(m.refined_triangles[0], (std::vector<int32_t>{0, 1, 2}));
    EXPECT_FLOAT_EQ(m.refined_weave_uv[0][2][1], 1e-3f);
    EXPECT_EQ(m.refined_region[0], 1);
  }
  {
    std::lock_guard<std::mutex> lock(haptic.mu);
    const auto& m = haptic.got.back();
    ASSERT_GT(m.num_samples, 0);
    EXPECT_EQ(m.num_fingers, 2);
    EXPECT_FLOAT_EQ(m.force[0][1][2], 1.5f);
    EXPECT_TRUE(m.in_contact[0][1]);
    EXPECT_FALSE(m.in_contact[0][0]);
    EXPECT_FLOAT_EQ(m.device_position[0][0][2], 0.03f);
    // Consecutive ticks within a message.
    for (int k = 1; k < m.num_samples; ++k) EXPECT_EQ(m.tick[k], m.tick[k - 1] + 1);
  }
  {
    std::lock_guard<std::mutex> lock(stats.mu);
    EXPECT_FLOAT_EQ(stats.got.back().period_error_max_us, 3.0f);
  }
  const HubStats s = hub.stats();
  EXPECT_GT(s.published[static_cast<int>(Topic::Cloth)], 0u);
  EXPECT_EQ(s.haptic_samples_dropped, 0u);
}

TEST(Hub, ALateJoinerGetsTheSceneFromTheQueryable) {
  Hub hub(options(), small_scene());
  ZenohSession client(ZenohSession::Json5{client_config()});
  hapticloth::scene_info_t si;
  bool got = false;
  ASSERT_TRUE(eventually([&] {
    zenoh_get(client, "hapticloth/*/scene", 1000, [&](const std::uint8_t* d, std::size_t n) {
      got = decode(d, n, si);
    });
    return got;
  }));
  EXPECT_EQ(si.server_name, "test");
  EXPECT_EQ(si.material_name, "cotton");
  EXPECT_DOUBLE_EQ(si.areal_density, 0.12);
  EXPECT_EQ(si.topology.num_triangles, 2);
  EXPECT_EQ(si.topology.triangles[1][1], 3);
  EXPECT_FLOAT_EQ(si.topology.weave_uv[1][1][1], 0.1f);
  EXPECT_DOUBLE_EQ(si.device_origin[2], 0.01);
  bool has_cloth = false;
  for (int i = 0; i < si.num_topics; ++i)
    has_cloth |= si.topics[i] == "cloth" && si.key_expressions[i] == "hapticloth/test/cloth" &&
                 si.lcm_channels[i] == "HAPTICLOTH_CLOTH";
  EXPECT_TRUE(has_cloth);
}

TEST(Hub, TrajectoryCommandsReachTheRemoteDeviceAndBadOnesAreRejectedWithAnEvent) {
  devices::DeviceOptions dopt;
  dopt.driver = "remote";
  devices::RemoteDevice dev(dopt);
  ASSERT_EQ(dev.configure(), "");
  devices::DeviceState st;
  dev.read(0.0, st);

  Hub hub(options(), small_scene());
  hapticloth::trajectory_cmd_t m;
  m.source = "test";
  m.seq = 1;
  m.finger = 0;
  m.frame = hapticloth::trajectory_cmd_t::FRAME_DEVICE;
  m.num_points = 1;
  m.times = {0.2};
  m.positions = {{st.finger[0].position.x(), st.finger[0].position.y(), st.finger[0].position.z() - 0.01}};
  EXPECT_NE(hub.handle_command(m).find("no remote device"), std::string::npos);
  hub.set_command_sink(&dev);

  ZenohSession client(ZenohSession::Json5{client_config()});
  Collector<hapticloth::event_t> events(client, "hapticloth/test/events");
  ZenohPublisher cmd(client, "hapticloth/test/trajectory");
  std::vector<std::uint8_t> bytes;
  encode(m, bytes);
  ASSERT_TRUE(eventually([&] {  // until the Hub's subscriber is reached
    cmd.put(bytes.data(), bytes.size());
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    return hub.stats().commands_accepted > 0;
  }));
  dev.read(1.0, st);
  EXPECT_EQ(dev.commands_taken(), 1u);
  dev.read(1.2, st);
  EXPECT_NEAR(st.finger[0].position.z(), m.positions[0][2], 1e-12);

  // Scene frame: the Hub maps it to the device frame (origin 1 cm up).
  hapticloth::trajectory_cmd_t s = m;
  s.frame = hapticloth::trajectory_cmd_t::FRAME_SCENE;
  s.positions[0][2] += 0.01;
  EXPECT_EQ(hub.handle_command(s), "");
  dev.read(1.2, st);
  dev.read(1.5, st);
  EXPECT_NEAR(st.finger[0].position.z(), m.positions[0][2], 1e-12);

  m.seq = 2;
  m.positions[0][0] = 1.0;  // outside the workspace
  encode(m, bytes);
  cmd.put(bytes.data(), bytes.size());
  ASSERT_TRUE(eventually([&] {
    hub.flush();
    std::lock_guard<std::mutex> lock(events.mu);
    for (const auto& e : events.got)
      if (e.kind == "command_rejected" && e.text.find("seq 2") != std::string::npos &&
          e.text.find("outside the workspace") != std::string::npos)
        return true;
    return false;
  }));
  EXPECT_GE(hub.stats().commands_rejected, 2u);
}

// Issue 36 item 9: a log that cannot be written (a full disk; /dev/full here, which the
// server's claim refuses by name before a session) lost every message with exit 0. The Hub
// counts the messages LCM's file provider could not write and finish() says so.
TEST(Hub, SaysWhenTheLcmLogCannotBeWritten) {
  TransportOptions o = options("/dev/full");
  o.zenoh = false;
  Hub hub(o, small_scene());
  hub.on_sim_step(snapshot(0.05, 5));
  for (int k = 0; k < 200; ++k) hub.post_event("note", std::string(200, 'x'));  // past stdio's buffer
  hub.flush();
  const std::string lost = hub.finish();
  EXPECT_NE(lost.find("LCM log /dev/full: "), std::string::npos) << lost;
  EXPECT_NE(lost.find("messages could not be written"), std::string::npos) << lost;
}

TEST(Hub, WritesAnLcmLogThatReadsBack) {
  const auto path = std::filesystem::temp_directory_path() /
                    ("hapticloth_test_hub_" + std::to_string(::getpid()) + ".lcmlog");
  {
    TransportOptions o = options(path.string());
    o.zenoh = false;
    Hub hub(o, small_scene());
    for (int k = 0; k < 50; ++k) {
      haptics::HapticReport r;
      r.time = k * 1e-3;
      r.tick = k;
      hub.on_haptic_tick(r, devices::DeviceState{}, devices::DeviceCommand{});
    }
    hub.on_sim_step(snapshot(0.05, 5));
    hub.post_event("started", "log test");
    hub.flush();
  }
  lcm_eventlog_t* log = lcm_eventlog_create(path.c_str(), "r");
  ASSERT_NE(log, nullptr);
  std::set<std::string> channels;
  int haptic_samples = 0;
  for (int k = 0; k < 10000; ++k) {
    lcm_eventlog_event_t* e = lcm_eventlog_read_next_event(log);
    if (!e) break;
    channels.insert(std::string(e->channel, e->channellen));
    if (std::string(e->channel, e->channellen) == "HAPTICLOTH_HAPTICS") {
      hapticloth::haptic_state_t m;
      ASSERT_TRUE(decode(static_cast<const std::uint8_t*>(e->data), e->datalen, m));
      haptic_samples += m.num_samples;
    }
    lcm_eventlog_free_event(e);
  }
  lcm_eventlog_destroy(log);
  std::filesystem::remove(path);
  for (const char* c : {"HAPTICLOTH_SCENE", "HAPTICLOTH_TOPOLOGY", "HAPTICLOTH_CLOTH",
                        "HAPTICLOTH_HAPTICS", "HAPTICLOTH_EVENTS"})
    EXPECT_TRUE(channels.count(c)) << c;
  EXPECT_EQ(haptic_samples, 50);
}

TEST(Hub, TheRealTimeSideDoesNotAllocate) {
  TransportOptions o = options();
  o.zenoh = false;
  Hub hub(o, small_scene());
  const haptics::ClothSnapshot snap = snapshot(0.0, 1);
  haptics::HapticReport r;
  haptics::LoopStats ls;
  test::AllocationGuard guard;
  for (int k = 0; k < 2000; ++k) {
    r.tick = k;
    hub.on_haptic_tick(r, devices::DeviceState{}, devices::DeviceCommand{});
    if (k % 10 == 0) hub.on_sim_step(snap);
    if (k % 1000 == 0) hub.on_loop_stats(ls);
  }
  EXPECT_EQ(guard.count(), 0u);
}

}  // namespace
}  // namespace hapticloth::transport
