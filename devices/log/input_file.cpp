#include "log/input_file.hpp"

#include <sys/stat.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

namespace hapticloth::devices {

namespace {
std::string mib(std::uint64_t bytes) {
  std::ostringstream os;
  os << (bytes >> 20) << " MiB";
  return os.str();
}
}  // namespace

std::string check_input_file(const std::string& path, std::uint64_t max_bytes) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return path + ": cannot open file (" + std::strerror(errno) + ")";
  if (S_ISDIR(st.st_mode)) return path + ": is a folder, not a file";
  if (!S_ISREG(st.st_mode))
    return path + ": not a regular file (a device, FIFO or socket is not read as input)";
  if (max_bytes > 0 && static_cast<std::uint64_t>(st.st_size) > max_bytes)
    return path + ": " + std::to_string(st.st_size) + " bytes, more than the " + mib(max_bytes) +
           " this kind of file may have";
  return "";
}

std::string read_input_file(const std::string& path, std::uint64_t max_bytes, std::string& text) {
  if (std::string e = check_input_file(path, max_bytes); !e.empty()) return e;
  std::ifstream in(path, std::ios::binary);
  if (!in) return path + ": cannot open file";
  std::ostringstream ss;
  ss << in.rdbuf();
  text = ss.str();
  return "";
}

}  // namespace hapticloth::devices
