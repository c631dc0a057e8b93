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

/// A file the program will write: a path, its folder exists, and what is there is a regular file
/// or nothing (not a folder, /dev/full or a FIFO); checked before any work, so that a long run
/// does not end in "cannot write".
inline CLI::Validator writable_file() {
  return CLI::Validator(
      [](std::string& path) -> std::string {
        namespace fs = std::filesystem;
        std::error_code ec;
        if (path.empty()) return "needs a path (an empty one names no file)";
        if (fs::is_directory(path, ec)) return path + " is a folder, not a file to write";
        if (fs::exists(path, ec) && !fs::is_regular_file(path, ec))
          return path + " is not a regular file (a device or FIFO); give a file to write";
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

/// A value that `why_wrong` accepts: it returns "" or why the value is wrong.
template <class F>
CLI::Validator satisfies(F why_wrong, const std::string& form) {
  return CLI::Validator([why_wrong](std::string& v) -> std::string { return why_wrong(v); }, form);
}

/// A non-empty value (an empty one would silently mean "the default").
inline CLI::Validator non_empty() {
  return satisfies([](const std::string& v) { return v.empty() ? std::string("must not be empty") : ""; },
                   "TEXT");
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
