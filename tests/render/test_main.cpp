// The hapticloth-render program (clients/render/main.cpp): its exit codes and messages for logs it
// cannot use, and the snapshot and frames it writes from a log.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include "render_fixtures.hpp"

namespace {

using namespace hapticloth::render;
using namespace hapticloth::render::test;

// --- the program -------------------------------------------------------------------------------

struct RunResult {
  int code = -1;
  std::string out;
};

RunResult run_render(const std::string& args) {
  const std::string err = temp_path("hapticloth_test_render.err");
  const std::string cmd = std::string(HAPTICLOTH_RENDER_EXE) + " " + args + " >" + err + " 2>&1";
  const int st = std::system(cmd.c_str());
  RunResult r;
  r.code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  const auto bytes = read_bytes(err);
  r.out.assign(bytes.begin(), bytes.end());
  fs::remove(err);
  return r;
}

TEST(Program, LogWithoutTopologyExitsWithCode2AndSaysWhy) {
  const Scene s = flat();
  const std::string path = temp_path("hapticloth_test_render_cli_notopo.lcm");
  {
    LogWriter w(path);
    w.write("HAPTICLOTH_CLOTH", state_msg(s, 0.1, 1.0f));
  }
  const RunResult r = run_render("--log " + path + " --snapshot " + temp_path("hapticloth_unused.png"));
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find(path + ": no cloth_topology_t message (was the log written by hapticloth-server?)"),
            std::string::npos)
      << r.out;
  fs::remove(path);

  const RunResult missing = run_render("--log " + temp_path("hapticloth_no_such_log.lcm") + " --snapshot " +
                                 temp_path("hapticloth_unused.png"));
  EXPECT_EQ(missing.code, 2) << missing.out;
  EXPECT_NE(missing.out.find("cannot open"), std::string::npos) << missing.out;
}

TEST(Program, SnapshotAndFramesFromALog) {
  const Scene s = flat();
  const std::string path = temp_path("hapticloth_test_render_cli.lcm");
  {
    LogWriter w(path);
    w.write("HAPTICLOTH_TOPOLOGY", topology_msg(s));
    for (int k = 0; k < 6; ++k) w.write("HAPTICLOTH_CLOTH", state_msg(s, 0.1 * k, 1.0f + 0.005f * k));
    w.write("HAPTICLOTH_HAPTICS", haptic_msg(0.0, 600, 2));
  }
  const std::string png = temp_path("hapticloth_test_render_snap.png");
  RunResult r = run_render("--log " + path + " --snapshot " + png + " --time 0.31 --size 300x200 --color weft");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("t = 0.3 s"), std::string::npos) << r.out;
  const Image img = decode_png(read_bytes(png));
  EXPECT_EQ(img.width, 300);
  EXPECT_EQ(img.height, 200);

  const std::string dir = temp_path("hapticloth_test_render_frames");
  fs::remove_all(dir);
  r = run_render("--log " + path + " --frames " + dir + " --fps 20 --size 160x120 --supersample 1");
  ASSERT_EQ(r.code, 0) << r.out;
  // 0 .. 0.5 s at 20 fps: 11 frames.
  EXPECT_TRUE(fs::exists(fs::path(dir) / "frame_00010.png"));
  EXPECT_FALSE(fs::exists(fs::path(dir) / "frame_00011.png"));
  fs::remove_all(dir);
  fs::remove(png);
  fs::remove(path);

  // Usage errors exit 2, the option named.
  EXPECT_EQ(run_render("--log " + path + " --snapshot x.png --size 12by5").code, 2);
  EXPECT_EQ(run_render("--log " + path + " --snapshot x.png --color plaid").code, 2);
}


}  // namespace
