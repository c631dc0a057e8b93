// Direct coupling: the fingertip proxies are solved with the global cloth in its implicit step
// (FingertipContact, on the simulation thread, at the haptic period). The haptic tick renders
// the force of the latest step: minus the sum of the contact forces the cloth got in it.
#pragma once

#include "haptics/modes/surface_contact.hpp"

namespace hapticloth::haptics {

class ProxyContact final : public SurfaceContact {
 public:
  explicit ProxyContact(double coupling_stiffness) : k_(coupling_stiffness) {}
  void touch(const ClothSnapshot& s, double now, double tick_dt, const Fingertip& tip,
             FingerReport& out) noexcept override;

 private:
  double k_;
};

}  // namespace hapticloth::haptics
