// Command-line checks shared by every program: numeric options must be finite and in range,
// named in the message (CLI11 prefixes the option: "--dt: must be ..."), and any usage error
// exits 2, the status the README documents for bad input (CLI11's own codes are 104-109).
#pragma once

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <string>

#include <CLI/CLI.hpp>

namespace hapticloth::opts {

/// A number in [lo, hi] (open at lo if `open_lo`: "> lo"). CLI::Range lets NaN through.
inline CLI::Validator number_in(double lo, double hi, bool open_lo = false,
                                const std::string& unit = "") {
  return CLI::Validator(
      [=](std::string& text) -> std::string {
        char* end = nullptr;
        const double v = std::strtod(text.c_str(), &end);
        std::ostringstream os;
        if (text.empty() || *end != '\0' || !std::isfinite(v)) {
          os << "must be a finite number" << (unit.empty() ? "" : " (" + unit + ")") << ", not '"
             << text << "'";
          return os.str();
        }
        if ((open_lo ? v <= lo : v < lo) || v > hi) {
          os << "must be " << (open_lo ? "> " : ">= ") << lo << " and <= " << hi
             << (unit.empty() ? "" : " " + unit) << ", not " << text;
          return os.str();
        }
        return "";
      },
      (open_lo ? "(" : "[") + std::to_string(lo) + ", " + std::to_string(hi) + "]");
}

/// A positive number up to `hi`.
inline CLI::Validator positive(double hi, const std::string& unit = "") {
  return number_in(0.0, hi, true, unit);
}

/// A file the program will write: its folder exists, and it is not a folder itself (checked
/// before any work, so that a long run does not end in "cannot write").
inline CLI::Validator writable_file() {
  return CLI::Validator(
      [](std::string& path) -> std::string {
        namespace fs = std::filesystem;
        std::error_code ec;
        if (fs::is_directory(path, ec)) return path + " is a folder, not a file to write";
        const fs::path dir = fs::path(path).parent_path();
        if (!dir.empty() && !fs::is_directory(dir, ec))
          return "cannot write " + path + ": the folder " + dir.string() + " does not exist";
        return "";
      },
      "FILE");
}

/// A new file the program will write (writable_file, and nothing there yet: a recording is
/// never overwritten).
inline CLI::Validator new_file() {
  return CLI::Validator(
      [](std::string& path) -> std::string {
        std::string e = writable_file()(path);
        if (!e.empty()) return e;
        std::error_code ec;
        if (std::filesystem::exists(path, ec)) return path + " exists (a recording is never overwritten)";
        return "";
      },
      "NEW_FILE");
}

/// Parses; on a usage error prints CLI11's message and returns 2 (0 for --help). Returns -1
/// when the program should go on.
inline int parse(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc == 0 ? 0 : 2;
  }
  return -1;
}

}  // namespace hapticloth::opts
