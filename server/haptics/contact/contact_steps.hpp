// The fingertip contact's rules that differ with the length of the step it is solved in
// (cloth::ContactSteps): direct coupling's short steps, one per haptic tick (1 ms), and the
// multirate path's long global steps (5-40 ms), which the haptic thread's local model follows.
// Every such difference is one function here, with its reason; FingertipContact asks the rules
// it was given once, from the integrator's configuration, and holds no flag of its own.
#pragma once

#include <Eigen/Core>

#include "cloth/integrator.hpp"

namespace hapticloth::haptics {

class ContactStepRules {
 public:
  using Vec3 = Eigen::Vector3d;
  virtual ~ContactStepRules() = default;

  /// Where the proxy is expected at the end of the step, from where it is (x), its own last
  /// displacement and how far its target moved since the last step.
  virtual Vec3 expected_proxy(const Vec3& x, const Vec3& last_displacement, const Vec3& target_moved) const = 0;
  /// How far the sphere is expected to move relative to a contact's point over the step, from
  /// the proxy's expected motion and the point's (place() tilts the contact's normal by the
  /// part across it): none in a short step, where it is a few hundredths of a millimetre.
  virtual Vec3 relative_motion(const Vec3& proxy_motion, const Vec3& point_motion) const = 0;
  /// The normal stiffness of the penalty pressure kw linearized at depth d (m).
  virtual double pressure_stiffness(double kw, double depth, double stiffening_depth) const = 0;
  /// The spring's stiffness the integrator's one-sided line search uses (0: none).
  virtual double line_search_stiffness(double kn) const = 0;
  /// The force through the fingertip's refined compliance c, in series with the coupling
  /// (reported as c times this beyond the global proxy), for the contact force F.
  virtual Vec3 series_force(const Vec3& axis, const Vec3& force) const = 0;
  /// Whether the refined compliance is solved with the step, along its axis
  /// (FingertipContact::couple_through_fingertip).
  virtual bool couples_through_fingertip() const = 0;
  /// Whether a contact released earlier in this step comes back with its friction state.
  virtual bool rejoins_with_state() const = 0;
  /// Whether a slide-to-stick switch after the free revisions waits for the next step.
  virtual bool defers_late_sticking() const = 0;
  /// Whether a sliding contact whose slide was scaled to nothing opposes the point's slip.
  virtual bool slides_against_slip() const = 0;
};

/// Direct coupling: the step is one haptic tick.
class ShortStepRules final : public ContactStepRules {
 public:
  // The proxy moves a few hundredths of a millimetre a tick: as in the last step.
  Vec3 expected_proxy(const Vec3& x, const Vec3& last_displacement, const Vec3&) const override {
    return x + last_displacement;
  }
  Vec3 relative_motion(const Vec3&, const Vec3&) const override { return Vec3::Zero(); }
  // Stiffening with depth, kw (1 + d / d_s): the sphere's contact patch grows with depth
  // (docs/contact.md, 'The model').
  double pressure_stiffness(double kw, double depth, double stiffening_depth) const override {
    return kw * (1.0 + depth / stiffening_depth);
  }
  double line_search_stiffness(double kn) const override { return kn; }
  // Along the step's axis, as couple_through_fingertip solves it.
  Vec3 series_force(const Vec3& axis, const Vec3& force) const override { return axis * axis.dot(force); }
  bool couples_through_fingertip() const override { return true; }
  // Fresh, a contact would stick to where it was at the start, slide, be released and come
  // back sticking again: the cycle a fast stroke's rim samples ran to the revision cap.
  bool rejoins_with_state() const override { return true; }
  // A contact that slides after the free revisions stays sliding to the next step, 1 ms later
  // (its magnitude still follows its normal force); otherwise contacts at the cone's edge flip
  // between stick and slide until the revision cap, and the step ends before the samples the
  // last solve pushed inside are added.
  bool defers_late_sticking() const override { return true; }
  // Kept at zero, the contact would slide frictionless for the rest of the step however hard
  // it pressed again, and a stroke's friction fall short of Coulomb's (docs/contact.md).
  bool slides_against_slip() const override { return true; }
};

/// The multirate path: a global step of 5-40 ms.
class LongStepRules final : public ContactStepRules {
 public:
  // The massless proxy follows the device: it moves as its target moved (exact for a steady
  // stroke). Its own last displacement is no guide, as a contact that lets go moves it
  // millimetres in one long step, and a prediction that far off puts the contacts' normals on
  // the wrong side.
  Vec3 expected_proxy(const Vec3& x, const Vec3&, const Vec3& target_moved) const override {
    return x + target_moved;
  }
  Vec3 relative_motion(const Vec3& proxy_motion, const Vec3& point_motion) const override {
    return proxy_motion - point_motion;
  }
  double pressure_stiffness(double kw, double, double) const override { return kw; }
  // The long steps revise their set as before, without the line search.
  double line_search_stiffness(double) const override { return 0.0; }
  // Isotropic: the multirate path's proxies have the spring 1 / (1/k + c).
  Vec3 series_force(const Vec3&, const Vec3& force) const override { return force; }
  bool couples_through_fingertip() const override { return false; }
  bool rejoins_with_state() const override { return false; }
  // A long step holds its friction state for the whole step and keeps revising it: deferring
  // there let a pinch carry less than the weight (docs/contact.md, 'The model').
  bool defers_late_sticking() const override { return false; }
  // The global step is only what the local model follows; its response model, following the
  // steps this rule gives, predicts the finger leaving the cloth mid-stroke (docs/contact.md,
  // 'Friction in the multirate path's steps').
  bool slides_against_slip() const override { return false; }
};

/// The rules of `steps` (stateless, shared).
inline const ContactStepRules& contact_step_rules(cloth::ContactSteps steps) {
  static const ShortStepRules short_steps;
  static const LongStepRules long_steps;
  return steps == cloth::ContactSteps::Short ? static_cast<const ContactStepRules&>(short_steps) : long_steps;
}

}  // namespace hapticloth::haptics
