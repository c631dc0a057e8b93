// The files a session writes are claimed for it (server/app/output_claim.hpp): a second claim
// of a path, as a second server makes, is refused with the path and the option named, and the
// file the first is writing is left whole; once the first lets go the path can be claimed again.
#include "app/output_claim.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "app/toml_file.hpp"
#include "support/temp_files.hpp"

using namespace hapticloth;

namespace {
std::string read_all(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}
}  // namespace

TEST(OutputClaim, ASecondClaimIsRefusedAndLeavesTheFileWhole) {
  const std::string path = test::temp_path(".lcm");
  {
    std::ofstream(path) << "the first session's log";
  }
  {
    app::OutputClaims first;
    first.claim(path, "--lcm-log");
    EXPECT_EQ(read_all(path), "the first session's log");  // claiming does not truncate
    app::OutputClaims second;
    try {
      second.claim(path, "--lcm-log");
      FAIL() << "a second claim of " << path << " was accepted";
    } catch (const app::ConfigError& e) {
      const std::string m = e.what();
      EXPECT_NE(m.find("--lcm-log " + path), std::string::npos) << m;
      EXPECT_NE(m.find("another running session is writing it"), std::string::npos) << m;
    }
    EXPECT_EQ(read_all(path), "the first session's log");
  }
  app::OutputClaims again;  // the first session has ended
  EXPECT_NO_THROW(again.claim(path, "--lcm-log"));
}

TEST(OutputClaim, CreatesAMissingFileAndRefusesOneItCannotWrite) {
  app::OutputClaims c;
  const std::string path = test::temp_path(".csv");
  c.claim(path, "--record");
  EXPECT_TRUE(std::ifstream(path).good());
  c.claim("", "--record");  // nothing to claim
  try {
    c.claim(path + ".d/x.csv", "--record");
    FAIL() << "a path in a missing folder was claimed";
  } catch (const app::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("--record " + path + ".d/x.csv: cannot write it"),
              std::string::npos) << e.what();
  }
}

// Issue 36 item 9: /dev/full as a log was taken and the session "succeeded" with nothing written.
TEST(OutputClaim, RefusesWhatIsNotARegularFile) {
  app::OutputClaims c;
  try {
    c.claim("/dev/full", "--lcm-log");
    FAIL() << "/dev/full was claimed as a log";
  } catch (const app::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("--lcm-log /dev/full: not a regular file"), std::string::npos) << e.what();
  }
}

// A start that fails after the claims (a bad endpoint) leaves no empty file behind; a file that
// was there before stays, and a session that ran keeps what it wrote.
TEST(OutputClaim, AFailedStartRemovesOnlyTheFilesItCreated) {
  const std::string made = test::temp_path(".csv"), there = test::temp_path(".lcm"),
                    kept = test::temp_path(".csv");
  std::ofstream(there) << "an older log";
  {
    app::OutputClaims c;
    c.claim(made, "--record");
    c.claim(there, "--lcm-log");
  }
  EXPECT_FALSE(std::ifstream(made).good());
  EXPECT_EQ(read_all(there), "an older log");
  {
    app::OutputClaims c;
    c.claim(kept, "--record");
    c.keep();
  }
  EXPECT_TRUE(std::ifstream(kept).good());
}
