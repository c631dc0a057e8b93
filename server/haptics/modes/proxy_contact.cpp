#include "haptics/modes/proxy_contact.hpp"

namespace hapticloth::haptics {

void ProxyContact::touch(const ClothSnapshot& s, double, double, const Fingertip& tip,
                         FingerReport& out) noexcept {
  const ProxyResult& r = s.proxy[tip.finger];
  const bool valid = s.time >= 0.0 && r.valid;
  out.position = tip.centre;
  out.velocity = tip.velocity;
  out.proxy = valid ? r.proxy : tip.centre;
  out.force = valid ? r.force : Vec3::Zero();
  // The spring stretched from the fingertip the step pulled towards (r.target) to the proxy.
  out.spring = valid && r.in_contact ? Vec3(k_ * (r.proxy - r.target)) : Vec3::Zero();
  report_proxy_contact(r, valid && r.in_contact, k_, out);
}

}  // namespace hapticloth::haptics
