#include "cloth/simd_level.hpp"

namespace hapticloth::cloth {

const char* to_string(SimdLevel level) {
  switch (level) {
    case SimdLevel::Baseline: return "baseline";
    case SimdLevel::Avx2: return "avx2";
    case SimdLevel::Avx512: return "avx512";
  }
  return "unknown";
}

std::optional<SimdLevel> parse_simd_level(const std::string& name) {
  for (SimdLevel l : {SimdLevel::Baseline, SimdLevel::Avx2, SimdLevel::Avx512})
    if (name == to_string(l)) return l;
  return std::nullopt;
}

std::vector<SimdLevel> built_levels() {
#if defined(__x86_64__)
  return {SimdLevel::Baseline, SimdLevel::Avx2, SimdLevel::Avx512};
#else
  return {SimdLevel::Baseline};
#endif
}

bool runs_here(SimdLevel level) {
#if defined(__x86_64__)
  // The features each level's translation unit is compiled for (-march=x86-64-v3, -v4), as the
  // psABI's micro-architecture levels define them.
  __builtin_cpu_init();
  const bool v3 = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") &&
                  __builtin_cpu_supports("bmi") && __builtin_cpu_supports("bmi2") &&
                  __builtin_cpu_supports("movbe") && __builtin_cpu_supports("f16c");
  switch (level) {
    case SimdLevel::Baseline: return true;
    case SimdLevel::Avx2: return v3;
    case SimdLevel::Avx512:
      return v3 && __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
             __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512vl") &&
             __builtin_cpu_supports("avx512cd");
  }
  return false;
#else
  return level == SimdLevel::Baseline;
#endif
}

std::vector<SimdLevel> levels_here() {
  std::vector<SimdLevel> out;
  for (SimdLevel l : built_levels())
    if (runs_here(l)) out.push_back(l);
  return out;
}

SimdLevel best_level() { return levels_here().back(); }

}  // namespace hapticloth::cloth
