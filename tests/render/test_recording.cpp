// The log reader (clients/render/recording): topology, states and haptics whatever the channel;
// a log without topology is a clear error.
#include <gtest/gtest.h>

#include "render_fixtures.hpp"

namespace {

using namespace hapticloth::render;
using namespace hapticloth::render::test;

TEST(Log, ReadsTopologyStatesAndHapticsWhateverTheChannel) {
  const Scene s = flat();
  const std::string path = temp_path("hapticloth_test_render_ok.lcm");
  {
    LogWriter w(path);
    w.write("SOME_OTHER_NAME", topology_msg(s));
    w.write("HAPTICLOTH_CLOTH", state_msg(s, 0.2, 1.0f));
    w.write("HAPTICLOTH_CLOTH", state_msg(s, 0.1, 1.0f));  // out of order
    w.write("HAPTICLOTH_CLOTH", state_msg(s, 0.3, 1.02f));
    hapticloth::cloth_state_t wrong = state_msg(s, 0.4, 1.0f);
    wrong.num_vertices = 3;
    wrong.positions.resize(3);
    w.write("HAPTICLOTH_CLOTH", wrong);
    w.write("HAPTICLOTH_HAPTICS", haptic_msg(0.1, 5, 2));
    w.write("HAPTICLOTH_HAPTICS", haptic_msg(0.2, 5, 2));
  }
  const Recording rec = read_lcm_log(path);
  ASSERT_EQ(rec.scene.triangles.size(), s.triangles.size());
  ASSERT_EQ(rec.frames.size(), 3u);
  EXPECT_EQ(rec.dropped, 1u);
  EXPECT_DOUBLE_EQ(rec.frames[0].time, 0.1);
  EXPECT_DOUBLE_EQ(rec.frames[2].time, 0.3);
  EXPECT_EQ(rec.frame_near(0.26), 2u);
  EXPECT_EQ(rec.frame_near(0.24), 1u);
  EXPECT_EQ(rec.frame_near(99.0), 2u);
  ASSERT_EQ(rec.haptics.size(), 10u);
  const HapticTick* h = rec.haptics_at(0.2035);
  ASSERT_NE(h, nullptr);
  EXPECT_DOUBLE_EQ(h->time, 0.203);
  ASSERT_EQ(h->fingers.size(), 2u);
  EXPECT_FLOAT_EQ(h->fingers[1].position.x(), 0.1f);
  EXPECT_FLOAT_EQ(h->fingers[0].force.y(), -3.0f);
  EXPECT_TRUE(h->fingers[0].contact);
  EXPECT_EQ(rec.haptics_at(0.0), &rec.haptics.front());
  fs::remove(path);
}

TEST(Log, MissingTopologyIsAClearError) {
  const Scene s = flat();
  const std::string path = temp_path("hapticloth_test_render_notopo.lcm");
  {
    LogWriter w(path);
    w.write("HAPTICLOTH_CLOTH", state_msg(s, 0.1, 1.0f));
  }
  try {
    read_lcm_log(path);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), path + ": no cloth_topology_t message (was the log written by hapticloth-server?)");
  }
  EXPECT_THROW(read_lcm_log(temp_path("hapticloth_no_such_log.lcm")), InputError);
  fs::remove(path);
}

TEST(Log, ReadsTheRefinedChildrenAndDropsAStateWhoseRegionTheMeshLacks) {
  const Scene s = flat();
  const std::string path = temp_path("hapticloth_test_render_refined.lcm");
  const auto with_child = [&](double time, int region) {
    hapticloth::cloth_state_t m = state_msg(s, time, 1.0f);
    m.num_refined_vertices = 3;
    m.num_refined_triangles = 1;
    m.num_refined_region = 1;
    m.refined_positions = {{0.0f, 0.0f, 0.0f}, {0.01f, 0.0f, 0.0f}, {0.0f, 0.01f, -0.002f}};
    m.refined_triangles = {{0, 1, 2}};
    m.refined_weave_uv = {{{0.0f, 0.0f}, {0.01f, 0.0f}, {0.0f, 0.01f}}};
    m.refined_region = {region};
    return m;
  };
  {
    LogWriter w(path);
    w.write("HAPTICLOTH_TOPOLOGY", topology_msg(s));
    w.write("HAPTICLOTH_CLOTH", with_child(0.1, 7));
    w.write("HAPTICLOTH_CLOTH", with_child(0.2, 288));  // flat() has 288 triangles
    hapticloth::cloth_state_t bad = with_child(0.3, 7);
    bad.refined_triangles[0][2] = 3;  // a child vertex it lacks: not a mesh
    w.write("HAPTICLOTH_CLOTH", bad);
  }
  const Recording rec = read_lcm_log(path);
  ASSERT_EQ(rec.frames.size(), 1u);
  EXPECT_EQ(rec.dropped, 1u);
  const RefinedFrame& r = rec.frames[0].refined;
  ASSERT_EQ(r.positions.size(), 3u);
  EXPECT_FLOAT_EQ(r.positions[2].z(), -0.002f);
  ASSERT_EQ(r.mesh.triangles.size(), 1u);
  EXPECT_EQ(r.mesh.triangles[0], (std::array<int, 3>{0, 1, 2}));
  EXPECT_FLOAT_EQ(r.mesh.weave_uv[0][1][0], 0.01f);
  EXPECT_EQ(r.region, std::vector<int>{7});
  fs::remove(path);
}

}  // namespace
