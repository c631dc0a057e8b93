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


}  // namespace
