// Input files are regular files of bounded size (devices/log/input_file.hpp): a device, a FIFO
// or a folder is refused by name before anything reads it, and so is a file over the cap (a
// sparse one, so the test writes nothing).
#include "log/input_file.hpp"

#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "support/temp_files.hpp"

using namespace hapticloth::devices;

TEST(InputFile, ARegularFileIsReadWhole) {
  const std::string p = hapticloth::test::write_temp("name = \"x\"\n", ".toml");
  std::string text;
  EXPECT_EQ(read_input_file(p, kMaxConfigBytes, text), "");
  EXPECT_EQ(text, "name = \"x\"\n");
  std::filesystem::remove(p);
}

TEST(InputFile, RefusesWhatIsNotARegularFileByName) {
  EXPECT_EQ(check_input_file("/dev/zero", kMaxConfigBytes),
            "/dev/zero: not a regular file (a device, FIFO or socket is not read as input)");
  const std::string fifo = hapticloth::test::temp_path(".fifo");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::string text;
  EXPECT_NE(read_input_file(fifo, kMaxConfigBytes, text).find(fifo + ": not a regular file"), std::string::npos);
  std::filesystem::remove(fifo);
  EXPECT_EQ(check_input_file("/tmp", 0), "/tmp: is a folder, not a file");
  EXPECT_NE(check_input_file("/no/such/file.toml", 0).find("/no/such/file.toml: cannot open file"), std::string::npos);
}

TEST(InputFile, RefusesAFileOverItsCap) {
  const std::string p = hapticloth::test::temp_path(".toml");
  std::filesystem::resize_file((std::ofstream(p), p), (2ull << 30));  // sparse: 2 GiB of nothing
  const std::string e = check_input_file(p, kMaxConfigBytes);
  EXPECT_EQ(e, p + ": 2147483648 bytes, more than the 64 MiB this kind of file may have");
  EXPECT_EQ(check_input_file(p, 0), "");  // no cap: an LCM log is streamed
  std::filesystem::remove(p);
}
