// Input files (scenes, materials, meshes, trajectories, device logs, LCM logs, configs) are
// refused unless they are regular files of bounded size, before anything reads them: a FIFO,
// a device such as /dev/zero, or a multi-gigabyte file would otherwise hang the reader or eat
// the machine's memory. The error names the file.
#pragma once

#include <cstdint>
#include <string>

namespace hapticloth::devices {

/// Size caps, bytes. A text file that configures a run (TOML, JSON5, OBJ) and a trajectory are
/// far below them; a device log of an hour at 1 kHz with two fingers is about 0.7 GB.
inline constexpr std::uint64_t kMaxConfigBytes = 64ull << 20;       ///< TOML, JSON5
inline constexpr std::uint64_t kMaxMeshBytes = 512ull << 20;        ///< OBJ
inline constexpr std::uint64_t kMaxDataBytes = 2ull << 30;          ///< CSV logs, trajectories

/// "" if `path` is a regular file of at most `max_bytes` (0: any size), else "PATH: why".
std::string check_input_file(const std::string& path, std::uint64_t max_bytes);

/// Reads the whole file after check_input_file; "" or "PATH: why".
std::string read_input_file(const std::string& path, std::uint64_t max_bytes, std::string& text);

}  // namespace hapticloth::devices
