#include "haptics/proxy_contact.hpp"

namespace hapticloth::haptics {

void ProxyContact::touch(const ClothSnapshot& s, double, double, const Fingertip& tip,
                         FingerReport& out) noexcept {
  const ProxyResult& r = s.proxy[tip.finger];
  const bool valid = s.time >= 0.0 && r.valid;
  out.position = tip.centre;
  out.velocity = tip.velocity;
  out.proxy = valid ? r.proxy : tip.centre;
  out.force = valid ? r.force : Vec3::Zero();
  out.in_contact = valid && r.in_contact;
  out.slipping = out.in_contact && r.slipping;
  out.normal = r.normal;
  out.contact = r.contact;
  out.triangle = out.in_contact ? r.triangle : -1;
  for (int i = 0; i < 3; ++i) out.bary[i] = r.bary[i];
  out.stiffness = out.in_contact ? k_ : 0.0;
}

}  // namespace hapticloth::haptics
