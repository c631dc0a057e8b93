// Local refinement under the fingertips (paper 4.2.2): where the global mesh does not resolve a
// fingertip's contact patch, a refined child mesh of the cloth around the contact
// (MeshRefiner) is pressed with the force the global step rendered (RefinedContact), and the
// compliance the global mesh lacks goes in series with that fingertip's virtual coupling for
// the next step (FingertipContact::set_refined_compliance). docs/contact.md gives the design,
// why it was chosen and its figures.
//
// Owned by the simulation thread: after each global step it follows the cloth, re-centres a
// child whose contact has moved on, and settles each child a few Newton iterations (warm
// started from the last step, so a held press converges over steps).
#pragma once

#include <array>
#include <memory>
#include <optional>
#include <string>

#include "haptics/contact/fingertip_contact.hpp"
#include "haptics/refinement/refined_contact.hpp"
#include "haptics/refinement/refined_mesh.hpp"

namespace hapticloth::haptics {

struct RefinementParams {
  /// m: the child's edge at the contact point; 0 = fingertip radius / 8 (the global contact's
  /// sample spacing).
  double finest = 0.0;
  /// Child edge / distance from the contact point. Measured on the drum (docs/contact.md, 'Local
  /// refinement under the fingertips'):
  /// 1.0 keeps every uniform mesh of 2-25 mm within 2.6% of the exact solution with 170-300
  /// child vertices; 0.5 within 1.2% with 500.
  double grading = 1.0;
  /// The global mesh resolves the contact patch where the touched triangle's longest edge is at
  /// most this many finest edges: no child there.
  double resolved = 1.0;
  int iterations = 2;  ///< Newton iterations per step (a new child: 4x)
  /// m/N: the most compliance put in series with a coupling. A membrane without bending has
  /// almost no stiffness of its own where it is nearly slack, and the child then measures what
  /// the global mesh lacks as c ~ ln(h / a) / (2 pi T), large where the tension T is small (the
  /// middle of the hanging square). In series with the coupling that leaves the fingertip a
  /// spring of a few N/m along the normal, and the 1 ms contact solve loses its proxy through the
  /// draping cloth (docs/contact.md, "A bound on the compliance"). At 0.05 m/N the spring is at
  /// least 20 N/m; where the bound acts the forces are under a millinewton, below what a
  /// fingertip detects (29-44 mN).
  double max_compliance = 0.05;
  /// N: the least normal force whose extra depth is taken as a compliance. Under it the depth
  /// over the force is the child's settling lag and a first touch's geometry, not the cloth's
  /// response, and the compliance it gave held a pinch's squeeze far under k x depth (docs/
  /// contact.md, "The device's limit on the chain, and no compliance from a first touch");
  /// under it the last compliance stays (none on a first touch). 10 mN is under the 29-44 mN a
  /// fingertip detects.
  double min_force = 0.01;
};

/// Whether to refine where the global mesh does not resolve the contact patch. Auto and On: on
/// both paths, direct coupling and the response model (mesh_needs_refinement decides where);
/// Off never. (The patch model is its own refinement: the key is refused with it.)
enum class Refine { Auto, On, Off };
inline const char* to_string(Refine r) { return r == Refine::Auto ? "auto" : r == Refine::On ? "on" : "off"; }
inline bool refines(Refine r) { return r != Refine::Off; }

/// m: the child's edge at the contact point for a fingertip of `radius`.
double finest_edge(const RefinementParams& p, double radius);
/// The cloth's longest rest edge, m.
double longest_rest_edge(const cloth::ClothModel& m);
/// Whether some triangle is coarser than what resolves a fingertip's contact patch: the one rule
/// for the simulation (a LocalRefinement is made) and the stage line.
bool mesh_needs_refinement(const cloth::ClothModel& m, const RefinementParams& p, double radius);

/// What a refinement update takes from a global step: the cloth's positions, and per finger the
/// step's proxy result and its proxy in the global cloth (FingertipContact::global_proxy).
struct RefinementInput {
  std::vector<Vec3> x;
  std::array<ProxyResult, kMaxFingers> result{};
  std::array<Vec3, kMaxFingers> proxy{};
  int fingers = 0;
  /// From the step's contact; `x` keeps its size (no allocation after the first).
  void take(const cloth::ClothState& s, const FingertipContact& contact, int fingers);
};

class LocalRefinement {
 public:
  LocalRefinement(const cloth::ClothModel& global, const ContactParams& contact,
                  const Vec3& gravity, const RefinementParams& p);

  /// After a global step: the children follow the cloth and carry the forces of the step's
  /// fingertips; series(f) is then what the next step puts in series with finger f.
  void update(const RefinementInput& in);

  /// Finger f's child, if it has one now.
  const RefinedContact* child(int f) const { return child_[f].get(); }
  /// What the next step puts in series with finger f: the compliance and the axis it acts along.
  const SeriesCompliance& series(int f) const { return compliance_[f]; }
  double finest() const { return spec_.finest; }
  double resolved_edge() const { return p_.resolved * spec_.finest; }
  std::uint64_t builds() const { return builds_; }

 private:
  std::optional<ClothPoint> touched_point(const ProxyResult& r) const;
  void build_child(int f, const ClothPoint& at, const std::vector<Vec3>& x);
  double series_depth(const RefinedContact& child, int f, const std::array<ChildFinger, kMaxFingers>& in_child) const;

  const cloth::ClothModel& g_;
  ContactParams cp_;
  Vec3 gravity_;
  RefinementParams p_;
  MeshRefiner refiner_;
  RefineSpec spec_;
  std::array<std::unique_ptr<RefinedContact>, kMaxFingers> child_;
  std::array<Vec3, kMaxFingers> anchor_{};  // rest point each child is centred on
  std::array<SeriesCompliance, kMaxFingers> compliance_{};
  std::uint64_t builds_ = 0;
};

}  // namespace hapticloth::haptics
