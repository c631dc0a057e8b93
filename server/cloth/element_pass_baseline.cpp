// The element pass at the build's baseline (x86-64-v2 on x86-64, NEON on aarch64): lanes of 2 doubles, one SSE or NEON register.
// CMakeLists.txt compiles this file with the level's -march (HAPTICLOTH_LEVEL_FLAGS).
#define HAPTICLOTH_SIMD_NS simd_baseline
#define HAPTICLOTH_SIMD_LANES 2
#define HAPTICLOTH_SIMD_LEVEL SimdLevel::Baseline
#include "cloth/element_pass_lanes.hpp"
