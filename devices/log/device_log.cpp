#include "log/device_log.hpp"
#include "log/input_file.hpp"

#include "hal/rt_handoff.hpp"

#include <cerrno>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <mutex>
#include <thread>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>

namespace hapticloth::devices {

struct DeviceLogWriter::Impl {
  explicit Impl(std::size_t capacity) : ring(capacity) {}
  SpscRing<LogRow> ring;
  std::thread writer;
  std::mutex m;
  std::condition_variable wake;
  bool stop = false;
};

namespace {
// How often the writer drains the ring and flushes the file.
constexpr auto kWriterPeriod = std::chrono::milliseconds(5);
}  // namespace

DeviceLogWriter::DeviceLogWriter(std::size_t capacity_rows)
    : impl_(std::make_unique<Impl>(capacity_rows)) {}

DeviceLogWriter::~DeviceLogWriter() { close(); }

std::string DeviceLogWriter::open(const std::string& path) {
  close();
  file_ = std::fopen(path.c_str(), "w");
  if (!file_) return path + ": cannot write the device log (" + std::strerror(errno) + ")";
  path_ = path;
  write_error_ = false;
  written_ = 0;
  dropped_ = 0;
  std::fprintf(file_, "time,finger,x,y,z,vx,vy,vz,buttons,fx,fy,fz\n");
  std::fflush(file_);
  impl_->stop = false;
  impl_->writer = std::thread([this] { run(); });
  return "";
}

void DeviceLogWriter::record(double time, int fingers, const DeviceState& s,
                             const DeviceCommand& c) noexcept {
  if (!file_) return;
  for (int i = 0; i < fingers && i < kMaxFingers; ++i) {
    LogRow r;
    r.time = time;
    r.finger = i;
    r.x = s.finger[i].position;
    r.v = s.finger[i].velocity;
    r.buttons = s.finger[i].buttons;
    r.f = c.force[i];
    if (!impl_->ring.push(r)) dropped_.fetch_add(1, std::memory_order_relaxed);
  }
}

void DeviceLogWriter::drain() {
  LogRow r;
  std::uint64_t n = 0;
  while (impl_->ring.pop(r)) {
    if (std::fprintf(file_, "%.9g,%d,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%u,%.9g,%.9g,%.9g\n", r.time,
                     r.finger, r.x.x(), r.x.y(), r.x.z(), r.v.x(), r.v.y(), r.v.z(), r.buttons,
                     r.f.x(), r.f.y(), r.f.z()) < 0)
      write_error_ = true;
    ++n;
  }
  if (n > 0 && std::fflush(file_) != 0) write_error_ = true;
  written_.fetch_add(n, std::memory_order_relaxed);
}

void DeviceLogWriter::run() {
  std::unique_lock<std::mutex> lock(impl_->m);
  while (!impl_->stop) {
    impl_->wake.wait_for(lock, kWriterPeriod, [&] { return impl_->stop; });
    drain();
  }
}

std::string DeviceLogWriter::close() {
  if (!file_) return "";
  {
    std::lock_guard<std::mutex> lock(impl_->m);
    impl_->stop = true;
  }
  impl_->wake.notify_all();
  impl_->writer.join();
  drain();  // rows pushed after the writer's last pass
  const bool ok = std::fclose(file_) == 0 && !write_error_;
  file_ = nullptr;
  return ok ? "" : path_ + ": error while writing the device log";
}

std::vector<std::string> split_csv(const std::string& line) {
  std::vector<std::string> cols;
  std::stringstream ss(line);
  std::string c;
  while (std::getline(ss, c, ',')) {
    const auto b = c.find_first_not_of(" \t\r"), e = c.find_last_not_of(" \t\r");
    cols.push_back(b == std::string::npos ? "" : c.substr(b, e - b + 1));
  }
  if (!line.empty() && line.back() == ',') cols.push_back("");
  return cols;
}

double parse_number(const std::string& text, const std::string& path, int line, const char* field) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || !std::isfinite(v))
    throw std::invalid_argument(path + ":" + std::to_string(line) + ": " + field + " '" + text +
                                "' is not a finite number");
  return v;
}

std::vector<LogRow> load_device_log(const std::string& path) {
  if (std::string e = check_input_file(path, kMaxDataBytes); !e.empty()) throw std::invalid_argument(e);
  std::ifstream in(path);
  if (!in) throw std::invalid_argument(path + ": cannot open the device log");
  std::string line;
  int ln = 0;
  std::map<std::string, int> col;
  std::vector<LogRow> rows;
  while (std::getline(in, line)) {
    ++ln;
    if (line.find_first_not_of(" \t\r") == std::string::npos || line[0] == '#') continue;
    const auto c = split_csv(line);
    if (col.empty()) {
      for (size_t i = 0; i < c.size(); ++i) col[c[i]] = static_cast<int>(i);
      for (const char* k : {"time", "finger", "x", "y", "z"})
        if (!col.count(k))
          throw std::invalid_argument(path + ":" + std::to_string(ln) + ": missing column '" + k +
                                      "' (header time,finger,x,y,z[,vx,vy,vz,buttons,fx,fy,fz])");
      continue;
    }
    auto get = [&](const char* k, double dflt) {
      auto it = col.find(k);
      if (it == col.end()) return dflt;
      if (it->second >= static_cast<int>(c.size()))
        throw std::invalid_argument(path + ":" + std::to_string(ln) + ": missing field '" + k + "'");
      return parse_number(c[it->second], path, ln, k);
    };
    LogRow r;
    r.time = get("time", 0);
    const double fi = get("finger", 0);
    if (fi < 0 || fi >= kMaxFingers || fi != std::floor(fi))
      throw std::invalid_argument(path + ":" + std::to_string(ln) + ": finger must be an integer in 0.." +
                                  std::to_string(kMaxFingers - 1));
    r.finger = static_cast<int>(fi);
    r.x = Vec3(get("x", 0), get("y", 0), get("z", 0));
    r.v = Vec3(get("vx", 0), get("vy", 0), get("vz", 0));
    r.buttons = static_cast<std::uint32_t>(get("buttons", 0));
    r.f = Vec3(get("fx", 0), get("fy", 0), get("fz", 0));
    if (!rows.empty() && r.time < rows.back().time)
      throw std::invalid_argument(path + ":" + std::to_string(ln) + ": time goes backwards");
    rows.push_back(r);
  }
  if (col.empty()) throw std::invalid_argument(path + ": empty device log (no header)");
  if (rows.empty()) throw std::invalid_argument(path + ": the device log has no samples");
  return rows;
}

}  // namespace hapticloth::devices
