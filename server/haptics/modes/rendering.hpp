// How the simulation and the haptic loop share the fingertips: the rendering mode. Each mode is
// one unit in two halves, chosen here and nowhere else:
//   - Direct: the fingertip proxies solved with the whole cloth in a global step per haptic tick
//     (sim half ProxyCoupling, haptic half ProxyContact);
//   - Response: the multirate path (section 4.2: the global step is longer than the haptic
//     period) with the response model: the proxies solved with the cloth at each global step,
//     which hands over its linear response to the fingertips; the haptic loop renders from it
//     between steps, both fingers together (ResponseCoupling, ResponseContact);
//   - Patch: the multirate path with the paper's refined spring-mass patch per fingertip (4.2),
//     the rendered forces spread back on the global cloth by a kernel (4.3) (KernelCoupling,
//     PatchContact).
// Local refinement under the fingertips (LocalRefinement) is part of the proxy couplings.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "cloth/integrator.hpp"

namespace hapticloth::haptics {

/// The local model of the multirate path.
enum class LocalModel { Response, Patch };
inline const char* to_string(LocalModel m) { return m == LocalModel::Response ? "response" : "patch"; }

enum class Rendering { Direct, Response, Patch };
inline const char* to_string(Rendering r) {
  return r == Rendering::Direct ? "direct" : r == Rendering::Response ? "multirate (response)" : "multirate (patch)";
}
/// The mode of the multirate path with local model `m`, or direct coupling.
inline Rendering rendering(bool multirate, LocalModel m) {
  if (!multirate) return Rendering::Direct;
  return m == LocalModel::Response ? Rendering::Response : Rendering::Patch;
}
/// The haptic loop renders from a local model between global steps longer than its period.
inline bool multirate(Rendering r) { return r != Rendering::Direct; }
/// The fingertip proxies are solved with the cloth in its steps (all but the patch model).
inline bool solves_proxies(Rendering r) { return r != Rendering::Patch; }
/// What the global step's contacts are: direct coupling's short steps, or the multirate path's
/// long ones (cloth::ContactSteps).
inline cloth::ContactSteps contact_steps(Rendering r) {
  return r == Rendering::Direct ? cloth::ContactSteps::Short : cloth::ContactSteps::Long;
}

}  // namespace hapticloth::haptics
