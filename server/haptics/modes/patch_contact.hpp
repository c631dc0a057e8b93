// Local refinement (section 4.2): a subdivided patch per fingertip simulated at the haptic rate
// (LocalPatch), touched by a god-object proxy with Coulomb friction. The global simulation gets
// the rendered force spread over the cloth (KernelCoupling).
#pragma once

#include <array>
#include <memory>
#include <vector>

#include "haptics/modes/local_patch.hpp"
#include "haptics/modes/surface_contact.hpp"

namespace hapticloth::haptics {

class PatchContact final : public SurfaceContact {
 public:
  /// Set-up only (allocates the patches). k: the contact spring, N/m.
  PatchContact(const std::vector<std::array<int, 3>>& tris, const std::vector<Vec3>& rest,
               const std::vector<char>& pinned, const PatchParams& p, int fingers, double radius,
               double k, double damping, double friction);
  void touch(const ClothSnapshot& s, double now, double tick_dt, const Fingertip& tip,
             FingerReport& out) noexcept override;
  void release(int finger) noexcept override { proxy_[finger] = Proxy{}; }
  std::uint64_t patch_rebuilds() const override { return rebuilds_; }
  std::uint64_t patch_softened() const override { return softened_; }

 private:
  struct Proxy {
    bool contact = false;
    int side = 0;                // which side of the cloth the finger is on (+1 along the normal)
    Vec3 anchor = Vec3::Zero();  // friction anchor on the surface
  };
  void separate(Proxy& P) noexcept;
  bool pressing(Proxy& P, int finger, const Vec3& c, double h, double dist) noexcept;
  void render(LocalPatch& patch, const ClothSnapshot& s, double now, const PatchTouch& t,
              const SurfacePoint& sp, Proxy& P, FingerReport& out) noexcept;
  void step_untouched(LocalPatch& patch, const ClothSnapshot& s, double now, const PatchTouch& t,
                      Proxy& P) noexcept;

  const std::vector<std::array<int, 3>>& tris_;
  std::vector<std::unique_ptr<LocalPatch>> patch_;
  double r_, k_, b_, mu_;
  std::array<Proxy, kMaxFingers> proxy_{};
  std::array<std::uint64_t, kMaxFingers> impacts_{};
  std::uint64_t rebuilds_ = 0, softened_ = 0;
};

}  // namespace hapticloth::haptics
