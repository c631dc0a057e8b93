#include "haptics/modes/rendering_modes.hpp"

#include <algorithm>

#include "haptics/modes/kernel_coupling.hpp"
#include "haptics/modes/patch_contact.hpp"
#include "haptics/modes/proxy_contact.hpp"
#include "haptics/modes/proxy_coupling.hpp"
#include "haptics/modes/response_contact.hpp"

namespace hapticloth::haptics {

namespace {
double mean_edge(const cloth::ClothModel& m) {
  double edge = 0.0;
  int ne = 0;
  for (const auto& t : m.triangles)
    for (int k = 0; k < 3; ++k, ++ne)
      edge += (m.rest_positions[t[k]] - m.rest_positions[t[(k + 1) % 3]]).norm();
  return ne ? edge / ne : 0.0;
}
// The patch model's force-spreading kernel: the scene's radius, or max(fingertip radius,
// 2 x mean edge).
double kernel_radius(const cloth::ClothModel& m, const FingerParams& finger, const CouplingParams& c) {
  return c.kernel_radius > 0.0 ? c.kernel_radius : std::max(finger.radius, 2.0 * mean_edge(m));
}
}  // namespace

cloth::IntegratorConfig integrator_config(Rendering m, cloth::IntegratorConfig c, int fingers) {
  c.proxies = solves_proxies(m) ? fingers : 0;
  c.contact_steps = contact_steps(m);
  if (c.proxies > 0) c.alpha = 1.0;
  return c;
}

PatchParams patch_params(const PatchParams& scene, const cloth::ClothModel& model, const FingerParams& finger,
                         const CouplingParams& coupling, double haptic_rate) {
  PatchParams p = scene;
  p.areal_density = model.material.areal_density;
  p.stiffness = 0.5 * (model.material.weft.B[0][1] + model.material.warp.B[0][1]);
  p.contact_stiffness = finger.stiffness;
  p.haptic_period = 1.0 / haptic_rate;
  if (!(scene.radius > 0.0)) p.radius = std::max(2.0 * finger.radius, kernel_radius(model, finger, coupling));
  return p;
}

std::unique_ptr<SimCoupling> make_sim_coupling(Rendering m, const cloth::ClothModel& model,
                                               cloth::Integrator& integ, int fingers,
                                               const FingerParams& finger,
                                               const CouplingParams& coupling, const PatchParams& patch) {
  switch (m) {
    case Rendering::Direct:
      return std::make_unique<ProxyCoupling>(model, integ, fingers, finger, coupling,
                                             refines(coupling.refine));
    case Rendering::Response:
      return std::make_unique<ResponseCoupling>(model, integ, fingers, finger, coupling,
                                                refines(coupling.refine));
    case Rendering::Patch:
      return std::make_unique<KernelCoupling>(model, integ, fingers, kernel_radius(model, finger, coupling),
                                              coupling.finger_mass, patch.radius, coupling.margin);
  }
  return nullptr;
}

std::unique_ptr<SurfaceContact> make_surface_contact(Rendering m, const cloth::ClothModel& model,
                                                     int fingers, const FingerParams& finger,
                                                     const PatchParams& patch) {
  switch (m) {
    case Rendering::Direct:
      return std::make_unique<ProxyContact>(finger.stiffness);
    case Rendering::Response:
      return std::make_unique<ResponseContact>(finger.stiffness, finger.damping, finger.friction);
    case Rendering::Patch:
      return std::make_unique<PatchContact>(model.triangles, model.rest_positions, model.pinned, patch,
                                            fingers, finger.radius, finger.stiffness, finger.damping,
                                            finger.friction);
  }
  return nullptr;
}

}  // namespace hapticloth::haptics
