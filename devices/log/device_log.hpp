// The device log: what a device reported and what forces it was sent, one row per sample per
// finger. Written (streamed) by the mock and UDP drivers, read by the replay driver and tests.
// CSV header: time,finger,x,y,z,vx,vy,vz,buttons,fx,fy,fz (s, index, m, m/s, mask, N).
#pragma once

#include <atomic>
#include <cstdint>
#include <cstdio>
#include <memory>
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

/// Streams the device log to a CSV file while the device runs: the real-time side hands rows
/// to a fixed ring (never allocates, never blocks), a writer thread appends them to the file
/// and flushes it every few milliseconds, so a record is complete to within that of any stop.
/// A full ring drops rows, counted (dropped()).
class DeviceLogWriter {
 public:
  explicit DeviceLogWriter(std::size_t capacity_rows = 1u << 15);
  ~DeviceLogWriter();
  DeviceLogWriter(const DeviceLogWriter&) = delete;
  DeviceLogWriter& operator=(const DeviceLogWriter&) = delete;

  /// Creates (truncates) the file, writes the header and starts the writer. Returns "" or
  /// "PATH: cannot write the device log (reason)".
  std::string open(const std::string& path);
  bool is_open() const { return file_ != nullptr; }
  /// Real-time path: one row per finger.
  void record(double time, int fingers, const DeviceState& s, const DeviceCommand& c) noexcept;
  /// Writes what is left, closes the file, stops the writer. Returns "" or the write error.
  std::string close();

  const std::string& path() const { return path_; }
  std::uint64_t written() const { return written_.load(); }
  std::uint64_t dropped() const { return dropped_.load(); }

 private:
  void drain();
  void run();

  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::FILE* file_ = nullptr;
  std::string path_;
  bool write_error_ = false;
  std::atomic<std::uint64_t> written_{0}, dropped_{0};
};

/// Reads a device log. Throws std::invalid_argument "PATH:LINE: message" on bad input (missing
/// column, not a number, time going backwards, finger index out of range).
std::vector<LogRow> load_device_log(const std::string& path);

/// Splits a comma-separated line, trimming blanks (shared by the CSV readers of devices/ and the
/// measured KES points of server/app/kes.cpp).
std::vector<std::string> split_csv(const std::string& line);
/// Parses a finite number or throws std::invalid_argument "PATH:LINE: FIELD 'text' is not a number".
double parse_number(const std::string& text, const std::string& path, int line, const char* field);

}  // namespace hapticloth::devices
