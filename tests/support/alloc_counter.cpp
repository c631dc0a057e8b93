#include "support/alloc_counter.hpp"

#include <atomic>
#include <cstddef>

// glibc's own allocator entry points; our replacements count and forward to them.
extern "C" {
void* __libc_malloc(size_t);
void* __libc_calloc(size_t, size_t);
void* __libc_realloc(void*, size_t);
void* __libc_memalign(size_t, size_t);
}

namespace {
std::atomic<std::uint64_t> g_count{0};
inline void count() { g_count.fetch_add(1, std::memory_order_relaxed); }
}  // namespace

namespace hapticloth::test {
std::uint64_t allocation_count() { return g_count.load(std::memory_order_relaxed); }
}  // namespace hapticloth::test

// Replacing the C allocation functions catches C libraries (CHOLMOD) too; libstdc++'s
// operator new calls malloc, so C++ allocations are counted as well. Under AddressSanitizer or
// ThreadSanitizer (tools/sanitize) the sanitizer owns the allocator: no replacement, and the
// count stays 0 (the allocation checks are the normal build's).
#if !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
extern "C" void* malloc(size_t n) {
  count();
  return __libc_malloc(n);
}
extern "C" void* calloc(size_t a, size_t b) {
  count();
  return __libc_calloc(a, b);
}
extern "C" void* realloc(void* p, size_t n) {
  count();
  return __libc_realloc(p, n);
}
extern "C" int posix_memalign(void** out, size_t align, size_t n) {
  count();
  *out = __libc_memalign(align, n);
  return *out ? 0 : 12;  // ENOMEM
}
extern "C" void* aligned_alloc(size_t align, size_t n) {
  count();
  return __libc_memalign(align, n);
}
extern "C" void* memalign(size_t align, size_t n) {
  count();
  return __libc_memalign(align, n);
}
#endif
