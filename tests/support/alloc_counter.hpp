// Counts heap allocations made through operator new and malloc-family calls in this process,
// so a test can prove that a scope allocates nothing.
#pragma once

#include <cstdint>

namespace hapticloth::test {

/// Number of allocations so far (operator new, malloc, calloc, realloc, aligned allocations).
std::uint64_t allocation_count();

/// Counts allocations between construction and count().
class AllocationGuard {
 public:
  AllocationGuard() : start_(allocation_count()) {}
  std::uint64_t count() const { return allocation_count() - start_; }

 private:
  std::uint64_t start_;
};

}  // namespace hapticloth::test
