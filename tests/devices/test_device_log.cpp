// The device log (devices/log/device_log.cpp): streamed while the device runs, every row kept
// or counted as dropped, an unwritable path named; and the reader's errors.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

#include <unistd.h>

#include "log/device_log.hpp"
#include "support/alloc_counter.hpp"

using namespace hapticloth::devices;
namespace fs = std::filesystem;

namespace {
std::string tmp_csv(const char* tag) {
  return (fs::temp_directory_path() / ("hc-log-" + std::string(tag) + "-" + std::to_string(::getpid()) + ".csv"))
      .string();
}
int lines_in(const std::string& path) {
  std::ifstream in(path);
  std::string l;
  int n = 0;
  while (std::getline(in, l)) ++n;
  return n;
}
DeviceState state_at(double t) {
  DeviceState s;
  for (int f = 0; f < 2; ++f) s.finger[f].position = Vec3(t, f, 0.0);
  return s;
}
}  // namespace

// Rows reach the file while the device runs (the writer flushes every few ms), not at the end:
// a stop of any kind leaves the record complete to within that.
TEST(DeviceLogWriter, StreamsRowsToTheFileAsTheyCome) {
  const std::string path = tmp_csv("stream");
  DeviceLogWriter w;
  ASSERT_EQ(w.open(path), "");
  DeviceCommand c;
  {
    hapticloth::test::AllocationGuard guard;  // the real-time side never allocates
    for (int k = 0; k < 100; ++k) {
      c.force[0] = Vec3(0, 0, 0.01 * k);
      w.record(0.001 * k, 2, state_at(0.001 * k), c);
    }
    EXPECT_EQ(guard.count(), 0u);
  }
  int seen = 0;
  for (int i = 0; i < 200 && seen < 201; ++i) {  // at most 2 s
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    seen = lines_in(path);
  }
  EXPECT_EQ(seen, 201);  // header + 200 rows, before close()
  EXPECT_EQ(w.close(), "");
  EXPECT_EQ(w.written(), 200u);
  EXPECT_EQ(w.dropped(), 0u);
  const auto rows = load_device_log(path);
  ASSERT_EQ(rows.size(), 200u);
  EXPECT_NEAR(rows[2 * 42].f.z(), 0.42, 1e-12);
  EXPECT_NEAR(rows[2 * 42 + 1].x.y(), 1.0, 1e-12);
  fs::remove(path);
}

// A full buffer drops rows and counts them; the rows kept are all written.
TEST(DeviceLogWriter, CountsWhatAFullBufferDrops) {
  const std::string path = tmp_csv("full");
  DeviceLogWriter w(8);
  ASSERT_EQ(w.open(path), "");
  DeviceCommand c;
  for (int k = 0; k < 20; ++k) w.record(0.001 * k, 2, state_at(0.001 * k), c);
  EXPECT_EQ(w.close(), "");
  EXPECT_GT(w.dropped(), 0u);
  EXPECT_EQ(w.written() + w.dropped(), 40u);
  EXPECT_EQ(lines_in(path), 1 + static_cast<int>(w.written()));
  fs::remove(path);
}

TEST(DeviceLogWriter, NamesAnUnwritablePath) {
  DeviceLogWriter w;
  const std::string e = w.open("/nonexistent-folder/r.csv");
  EXPECT_NE(e.find("/nonexistent-folder/r.csv: cannot write the device log"), std::string::npos) << e;
  EXPECT_FALSE(w.is_open());
  DeviceCommand c;
  w.record(0.0, 2, DeviceState{}, c);  // nothing open: ignored
  EXPECT_EQ(w.close(), "");
}
