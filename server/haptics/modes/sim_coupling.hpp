// The simulation thread's half of a rendering mode (rendering.hpp): how the haptic loop's
// fingertips enter each global step, and what the step hands back to the haptic loop's half.
#pragma once

#include <cstdint>

#include "cloth/integrator.hpp"
#include "haptics/sim/handoff.hpp"

namespace hapticloth::haptics {

class FingertipContact;
class RefinementSchedule;

class SimCoupling {
 public:
  virtual ~SimCoupling() = default;
  /// Before the global step at loop time `now`: the haptic loop's latest report `r` (time < 0:
  /// none yet) coupled to the cloth `s`, for the integrator's next step.
  virtual void couple(const HapticReport& r, double now, cloth::ClothState& s) = 0;
  /// After the step, on the new state `s`: the step's results for the haptic loop's half.
  virtual void conclude(const cloth::ClothState& s) = 0;
  /// Into the snapshot the haptic loop reads (its positions and near flags already in): per
  /// finger the step's proxy, and what the mode's local model needs. `r`: the report the step
  /// took.
  virtual void fill(const HapticReport& r, const cloth::ClothState& s, ClothSnapshot& snap) = 0;

  /// The proxies' contact (nullptr when the mode solves no proxies).
  virtual const FingertipContact* fingertips() const { return nullptr; }
  /// The local refinement (nullptr when off, or not part of the mode).
  virtual const RefinementSchedule* refinement() const { return nullptr; }
  /// From now on, settle the local refinement beside the steps rather than within them (a
  /// real-time session: RefinementSchedule).
  virtual void refine_beside_steps() {}
  /// Snapshots in which a finger had more patch candidates than their room (patch model).
  virtual std::uint64_t patch_candidate_overflows() const { return 0; }
};

}  // namespace hapticloth::haptics
