// The element pass at AVX2 and FMA (x86-64-v3): lanes of 4 doubles, one ymm register.
// CMakeLists.txt compiles this file with the level's -march (HAPTICLOTH_LEVEL_FLAGS).
#define HAPTICLOTH_SIMD_NS simd_avx2
#define HAPTICLOTH_SIMD_LANES 4
#define HAPTICLOTH_SIMD_LEVEL SimdLevel::Avx2
#include "cloth/element_pass_lanes.hpp"
