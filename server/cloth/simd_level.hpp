// The instruction levels the element pass is built for, and which of them this CPU runs.
//
// Why levels: the element pass (element_lanes.hpp) works on lanes of doubles, and its speed
// depends on the lanes matching the CPU's vector registers: 8 doubles split into halves and
// spilled through memory on a CPU with 256-bit registers ran the step far slower than lanes of
// 4 (docs/performance.md, "Instruction levels"). Each level is compiled in its own
// translation unit with its own -march (CMakeLists.txt), so one binary holds all of them and
// picks at start-up; a build for a baseline CPU (HAPTICLOTH_PORTABLE) runs anywhere.
#pragma once

#include <optional>
#include <string>
#include <vector>

namespace hapticloth::cloth {

enum class SimdLevel {
  Baseline,  ///< the build's baseline (x86-64-v2: SSE4.2; NEON on aarch64): lanes of 2
  Avx2,      ///< x86-64-v3: AVX2 and FMA, lanes of 4
  Avx512,    ///< x86-64-v4: AVX-512 F/BW/DQ/VL, lanes of 8
};

/// "baseline", "avx2" or "avx512".
const char* to_string(SimdLevel level);
/// The level a name gives, or nothing for an unknown name.
std::optional<SimdLevel> parse_simd_level(const std::string& name);
/// The levels this binary holds (on x86-64 all three; elsewhere the baseline).
std::vector<SimdLevel> built_levels();
/// Whether this binary holds `level` and the CPU it runs on has its instructions.
bool runs_here(SimdLevel level);
/// The widest level that runs here.
SimdLevel best_level();
/// The levels that run here, narrowest first.
std::vector<SimdLevel> levels_here();

}  // namespace hapticloth::cloth
