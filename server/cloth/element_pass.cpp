#include "cloth/element_pass.hpp"

#include <stdexcept>
#include <string>

namespace hapticloth::cloth {

// Each level's table, from its own translation unit (element_pass_<level>.cpp).
namespace simd_baseline { const ElementKernels& level_kernels(); }
#if defined(__x86_64__)
namespace simd_avx2 { const ElementKernels& level_kernels(); }
namespace simd_avx512 { const ElementKernels& level_kernels(); }
#endif

const ElementKernels& element_kernels(SimdLevel level) {
  if (!runs_here(level))
    throw std::invalid_argument(std::string("simd level ") + to_string(level) +
                                ": this CPU lacks its instructions (it runs " +
                                to_string(best_level()) + ")");
  switch (level) {
#if defined(__x86_64__)
    case SimdLevel::Avx512: return simd_avx512::level_kernels();
    case SimdLevel::Avx2: return simd_avx2::level_kernels();
#endif
    default: return simd_baseline::level_kernels();
  }
}

}  // namespace hapticloth::cloth
