#include "log/device_log.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>

namespace hapticloth::devices {

void DeviceLogRecorder::reserve(size_t rows) {
  rows_.clear();
  rows_.reserve(rows);
  dropped_ = 0;
}

void DeviceLogRecorder::record(double time, int fingers, const DeviceState& s,
                               const DeviceCommand& c) noexcept {
  for (int i = 0; i < fingers && i < kMaxFingers; ++i) {
    if (rows_.size() == rows_.capacity()) {
      ++dropped_;
      continue;
    }
    LogRow r;
    r.time = time;
    r.finger = i;
    r.x = s.finger[i].position;
    r.v = s.finger[i].velocity;
    r.buttons = s.finger[i].buttons;
    r.f = c.force[i];
    rows_.push_back(r);  // within capacity: no allocation
  }
}

void DeviceLogRecorder::write_csv(const std::string& path) const {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (!f) throw std::runtime_error(path + ": cannot write the device log");
  std::fprintf(f, "time,finger,x,y,z,vx,vy,vz,buttons,fx,fy,fz\n");
  for (const auto& r : rows_)
    std::fprintf(f, "%.9g,%d,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%u,%.9g,%.9g,%.9g\n", r.time, r.finger,
                 r.x.x(), r.x.y(), r.x.z(), r.v.x(), r.v.y(), r.v.z(), r.buttons, r.f.x(), r.f.y(),
                 r.f.z());
  if (std::fclose(f) != 0) throw std::runtime_error(path + ": error while writing the device log");
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
