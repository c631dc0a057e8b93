// The scene's fingertip and its coupling to the cloth, as both halves of a rendering mode
// (rendering.hpp) take them.
#pragma once

#include "haptics/refinement/local_refinement.hpp"

namespace hapticloth::haptics {

struct FingerParams {
  double radius = 0.008;     ///< m, fingertip sphere
  double stiffness = 800.0;  ///< N/m, virtual coupling spring (clamped to the device's max_stiffness)
  double damping = 1.0;      ///< N s/m, virtual coupling damper
  double friction = 0.5;     ///< Coulomb coefficient (stick and slip)
  double contact_stiffness = 3e9;  ///< Pa/m, contact pressure per metre of depth into the sphere
  double max_force = 0.0;    ///< N, the most the coupling asks of the cloth (the gate's limit; 0 = none)
};

struct CouplingParams {
  /// Local refinement only: radius of the force-spreading kernel, m; 0 = max(fingertip radius,
  /// 2 x mean edge).
  double kernel_radius = 0.0;
  /// Local refinement only: effective moving mass of a fingertip and the device, kg, for the
  /// impact at contact onset (4.3.2); 0 turns the impact transfer off.
  double finger_mass = 0.05;
  /// Reach beyond the fingertip radius, m, within which the cloth is searched for contacts.
  double margin = 0.01;
  /// Local refinement under the fingertips (direct coupling and the response model;
  /// LocalRefinement): children where the global mesh does not resolve the contact patch.
  Refine refine = Refine::Auto;
  RefinementParams refinement{};
};

}  // namespace hapticloth::haptics
