// Temporary files of the device tests: a new name in the system's temp folder per call.
#pragma once

#include <filesystem>
#include <fstream>
#include <string>

#include <unistd.h>

namespace hapticloth::test {

/// A path not used before by this process, ending in `ext` (".csv").
inline std::string temp_path(const std::string& ext) {
  static int n = 0;
  return (std::filesystem::temp_directory_path() /
          ("hc-dev-" + std::to_string(::getpid()) + "-" + std::to_string(n++) + ext))
      .string();
}

/// Writes `text` to a new temp_path(ext) and returns the path.
inline std::string write_temp(const std::string& text, const std::string& ext) {
  const std::string p = temp_path(ext);
  std::ofstream(p) << text;
  return p;
}

}  // namespace hapticloth::test
