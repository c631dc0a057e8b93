#include "app/mesh_budget.hpp"

#include <unistd.h>

#include <cmath>
#include <iomanip>
#include <sstream>

namespace hapticloth::app {

std::uint64_t physical_memory() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGESIZE);
  return pages > 0 && page > 0 ? static_cast<std::uint64_t>(pages) * static_cast<std::uint64_t>(page)
                               : std::uint64_t{1} << 32;  // unknown: assume 4 GiB
}

long max_triangles_for_memory() {
  return static_cast<long>(0.5 * static_cast<double>(physical_memory()) / kBytesPerTriangle);
}

double pcg_step_ms(long triangles) {
  return kPcgRefStepMs * std::pow(static_cast<double>(triangles) / kPcgRefTriangles, kPcgExponent);
}

long max_triangles_for_haptics() {
  return static_cast<long>(kPcgRefTriangles * std::pow(kLongestGlobalStepMs / kPcgRefStepMs, 1.0 / kPcgExponent));
}

std::string memory_limit_error(long triangles) {
  const long most = max_triangles_for_memory();
  if (triangles <= most) return "";
  std::ostringstream os;
  os << std::fixed << std::setprecision(1) << triangles << " triangles need about "
     << triangles * kBytesPerTriangle / 1073741824.0 << " GiB (" << kBytesPerTriangle / 1e3
     << " kB a triangle); a scene may use half of this machine's "
     << static_cast<double>(physical_memory()) / 1073741824.0 << " GiB: at most " << most << " triangles";
  return os.str();
}

std::string haptic_budget_error(long triangles) {
  const long most = max_triangles_for_haptics();
  if (triangles <= most) return "";
  std::ostringstream os;
  os << std::fixed << std::setprecision(0) << triangles << " triangles: a global step of about "
     << pcg_step_ms(triangles) << " ms with PCG (measured " << std::setprecision(1) << kPcgRefStepMs
     << " ms at " << std::setprecision(0) << kPcgRefTriangles << " triangles, growing as triangles^"
     << std::setprecision(2) << kPcgExponent << std::setprecision(0) << "), longer than the " << kLongestGlobalStepMs
     << " ms the haptic loop renders between; a device session takes at most " << most
     << " triangles (--headless runs any mesh that fits in memory)";
  return os.str();
}

}  // namespace hapticloth::app
