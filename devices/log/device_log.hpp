// The device log: what a device reported and what forces it was sent, one row per sample per
// finger. Written by the mock and UDP drivers, read by the replay driver and by tests.
// CSV header: time,finger,x,y,z,vx,vy,vz,buttons,fx,fy,fz (s, index, m, m/s, mask, N).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "hal/device.hpp"

namespace hapticloth::devices {

struct LogRow {
  double time = 0.0;
  int finger = 0;
  Vec3 x = Vec3::Zero(), v = Vec3::Zero();
  std::uint32_t buttons = 0;
  Vec3 f = Vec3::Zero();
};

/// Fixed-capacity recorder: record() never allocates; rows past the capacity are counted.
class DeviceLogRecorder {
 public:
  void reserve(size_t rows);
  void record(double time, int fingers, const DeviceState& s, const DeviceCommand& c) noexcept;
  std::uint64_t dropped() const { return dropped_; }
  const std::vector<LogRow>& rows() const { return rows_; }
  /// Throws std::runtime_error naming the path if it cannot be written.
  void write_csv(const std::string& path) const;
  void clear() { rows_.clear(); dropped_ = 0; }

 private:
  std::vector<LogRow> rows_;
  std::uint64_t dropped_ = 0;
};

/// Reads a device log. Throws std::invalid_argument "PATH:LINE: message" on bad input (missing
/// column, not a number, time going backwards, finger index out of range).
std::vector<LogRow> load_device_log(const std::string& path);

/// Splits a comma-separated line, trimming blanks (shared by the CSV readers of devices/).
std::vector<std::string> split_csv(const std::string& line);
/// Parses a finite number or throws std::invalid_argument "PATH:LINE: FIELD 'text' is not a number".
double parse_number(const std::string& text, const std::string& path, int line, const char* field);

}  // namespace hapticloth::devices
