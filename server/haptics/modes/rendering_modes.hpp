// The one place a rendering mode (rendering.hpp) is turned into its two halves: the simulation
// thread's (SimCoupling) and the haptic thread's (SurfaceContact).
#pragma once

#include <memory>

#include "cloth/integrator.hpp"
#include "haptics/modes/local_patch.hpp"
#include "haptics/modes/params.hpp"
#include "haptics/modes/rendering.hpp"
#include "haptics/modes/sim_coupling.hpp"
#include "haptics/modes/surface_contact.hpp"

namespace hapticloth::haptics {

/// The integrator's configuration for mode `m`: the proxies it solves with the cloth and the
/// kind of steps their contacts take. Proxies are stiffer than the cloth: backward Euler
/// (alpha 1, L-stable) damps them; at alpha 0.5 they ring and the step blows up
/// (hapticloth-bench stability). The server's stages say so when the scene asks for less.
cloth::IntegratorConfig integrator_config(Rendering m, cloth::IntegratorConfig c, int fingers);

/// The patch model's patches on this cloth: the scene's `p`, with the spring model's modulus and
/// density from the material, the contact spring the coupling's, one tick the haptic period,
/// and (unless the scene sets it) the radius of the force-spreading kernel, at least 2
/// fingertip radii: enough triangles to hold the dent, few enough to step 32 times a tick.
PatchParams patch_params(const PatchParams& p, const cloth::ClothModel& model, const FingerParams& finger,
                         const CouplingParams& coupling, double haptic_rate);

/// The simulation half of mode `m` (the integrator `integ` configured by integrator_config).
std::unique_ptr<SimCoupling> make_sim_coupling(Rendering m, const cloth::ClothModel& model,
                                               cloth::Integrator& integ, int fingers,
                                               const FingerParams& finger,
                                               const CouplingParams& coupling, const PatchParams& patch);

/// The haptic half of mode `m`. Set-up only (allocates).
std::unique_ptr<SurfaceContact> make_surface_contact(Rendering m, const cloth::ClothModel& model,
                                                     int fingers, const FingerParams& finger,
                                                     const PatchParams& patch);

}  // namespace hapticloth::haptics
