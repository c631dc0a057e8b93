// The element pass at AVX-512 (x86-64-v4): lanes of 8 doubles, one zmm register.
// CMakeLists.txt compiles this file with the level's -march (HAPTICLOTH_LEVEL_FLAGS).
#define HAPTICLOTH_SIMD_NS simd_avx512
#define HAPTICLOTH_SIMD_LANES 8
#define HAPTICLOTH_SIMD_LEVEL SimdLevel::Avx512
#include "cloth/element_pass_lanes.hpp"
