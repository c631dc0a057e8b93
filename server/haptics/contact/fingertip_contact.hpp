// The fingertip as a rigid sphere touching the cloth wherever they overlap, solved with the cloth
// in the implicit step (constraint-based haptic rendering of a deformable body, with penalty
// contacts; docs/contact.md gives the design and the figures that chose it).
//
// Each fingertip is a massless proxy node of eq. 9 (cloth::ProxyNode), held to the device's
// fingertip by the virtual coupling (spring and damper). The cloth's surface is sampled at
// the nodes of a subdivision of each triangle, no more than `sample_spacing` apart (the
// trapezoidal rule on the sub-triangles: vertices and edges are samples too); every sample
// inside the sphere gets a one-sided penalty pressure kappa d (1 + d / d_s) at depth d over its
// area along the sphere's normal (linear in the multirate path's long steps), plus Coulomb
// friction (a tangential spring to an anchor on the sphere while it sticks, mu x its normal
// force while it slips). Each contact is a cloth::PointSpring: its stiffness is in the system
// matrix, so the light vertices under a finger stay stable at dt 1 ms. After the solve, a
// contact that would pull is dropped, a sample that would end inside the sphere is added, and
// Coulomb's law is checked on the solved step; if the set changed, the step is solved again
// (active set, with the integrator's line search in short steps).
//
// The force rendered to the user is minus the sum of the contact forces the cloth got in the
// step, which is the coupling spring's force because the proxy is massless (Newton's third law,
// exactly, tick by tick). The impact of section 4.3.2 needs no separate momentum transfer: the
// contact exchanges momentum through these equal and opposite forces.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "cloth/integrator.hpp"
#include "haptics/contact/broad_phase.hpp"
#include "haptics/contact/contact_steps.hpp"
#include "haptics/sim/handoff.hpp"

namespace hapticloth::haptics {

struct ContactParams {
  double radius = 0.008;              ///< m, fingertip sphere
  double coupling_stiffness = 800.0;  ///< N/m, device to proxy
  double coupling_damping = 1.0;      ///< N s/m, device to proxy
  double max_force = 0.0;             ///< N: the coupling spring asks no more (0 = no limit)
  double friction = 0.5;              ///< Coulomb coefficient per contact
  double pressure_stiffness = 3e9;    ///< Pa/m: contact pressure per metre of depth (kappa)
  double stiffening_depth = 0.25e-3;  ///< m, d_s: the pressure kappa d (1 + d / d_s) stiffens past it
  double sample_spacing = 0.0;        ///< m between surface samples; 0 = radius / 8
  double margin = 0.01;               ///< m beyond the sphere searched for samples
};

/// The device's fingertip for one step, in the scene frame.
struct FingerTarget {
  bool valid = false;      ///< false: no device sample yet (the proxy stays put, no force)
  Vec3 position = Vec3::Zero();  ///< at the end of the step, m
  Vec3 velocity = Vec3::Zero();  ///< m/s
};

/// What local refinement puts in series with a finger's coupling (LocalRefinement): the
/// compliance the global mesh lacks, and the direction along which the refined cloth takes it,
/// the refined membrane's own normal at the contact (RefinedContact::push). Zero axis: not
/// known, the step's contact normal is taken.
struct SeriesCompliance {
  double c = 0.0;                  ///< m/N
  Eigen::Vector3d axis = Eigen::Vector3d::Zero();  ///< unit
};

class FingertipContact final : public cloth::StepContacts {
 public:
  /// When a step ends (revise()): released contacts and friction corrections that add up to
  /// less than max(kResolveShare x the finger's normal force, kResolveFloor) wait for the next
  /// step, and a contact within kConeTolerance of its friction limit counts as on it. So on any
  /// tick a sliding fingertip's friction is within that sum plus kConeTolerance mu f_n of
  /// Coulomb's mu f_n.
  static constexpr double kResolveShare = 1e-2;
  static constexpr double kResolveFloor = 1e-3;  // N
  static constexpr double kConeTolerance = 5e-3;
  static double coulomb_bound(double normal_force, double mu);

  /// `integ` must have config().proxies >= fingers; its proxies start at `park` (m).
  FingertipContact(const cloth::ClothModel& model, const std::vector<std::array<int, 3>>& tris,
                   int fingers, const ContactParams& p, cloth::Integrator& integ);

  /// Before a step of length h: the proxies' coupling targets, and the contacts found on the
  /// state `s` handed to the integrator as point springs.
  void begin_step(const cloth::ClothState& s, const std::array<FingerTarget, kMaxFingers>& in,
                  double h);
  bool revise(const std::vector<Vec3>& x_new, const std::vector<cloth::ProxyNode>& proxies,
              bool short_of_solve, bool same_candidate) override;
  /// After the step (the new state `s`): the forces the cloth got, friction state, penetration.
  void end_step(const cloth::ClothState& s);

  const ProxyResult& result(int f) const { return out_[f]; }
  /// Local refinement (LocalRefinement): the compliance c (m/N) the global mesh lacks under
  /// finger f, in series with its coupling spring from the next step on: k_eff = 1 / (1/k + c).
  /// It is approached from the next step on at a bounded rate (approach_refined_compliance).
  void set_refined_compliance(int f, const SeriesCompliance& s) {
    refined_target_[f] = s.c;
    refined_push_[f] = s.axis;
  }
  /// Finger f's proxy in the global cloth, m (result().proxy is the fingertip: deeper by the
  /// refined compliance).
  const Vec3& global_proxy(int f) const { return integ_.proxies()[f].x; }
  /// Finger f's coupling stiffness in the last step, N/m.
  double coupling_stiffness(int f) const { return integ_.proxies()[f].stiffness; }
  /// Largest depth of any cloth point (vertex, edge or face) inside a fingertip sphere, m.
  double max_penetration() const { return max_pen_; }
  std::uint64_t active_samples() const { return samples_in_contact_; }

 private:
  struct Sample {  // one contact: a sample point against one fingertip
    int id = 0;    // global sample index (triangle offset + node)
    int tri = 0;
    double b[3] = {0, 0, 0};
    double w = 0.0;                // area, m^2
    Vec3 n = Vec3::Zero();         // unit normal of the spring: from the sphere's expected end (place)
    Vec3 nt = Vec3::Zero();        // unit normal of the friction plane: from the sphere at the start
    double depth0 = 0.0;           // depth at the start of the step (negative outside)
    double f0 = 0.0, kn = 0.0;     // normal force (N) and stiffness (N/m) there: the law linearized
    Vec3 x0 = Vec3::Zero();        // point at the start
    Vec3 anchor = Vec3::Zero();    // friction anchor, relative to the proxy centre
    bool slipping = false;
    double fn = 0.0;               // normal force at the end of the last step, N
    // This step's friction: sliding with force `slide` (N, on the cloth), or sticking.
    bool sliding = false;
    Vec3 slide = Vec3::Zero();
    bool release = false;  // would pull at the end of the solved step
  };
  struct Finger {
    std::vector<Sample> now, prev;  // this step's contacts (sorted by id), last step's
    std::vector<Sample> gone;       // contacts released by this step's re-solves
    std::vector<int> cand;          // candidate triangles (sized to the mesh: never overflows)
    int ncand = 0;
    // The query the candidates came from: its centre, its reach beyond the sphere, the broad
    // phase's displacement and refit count then (see covers()).
    Vec3 query_at = Vec3::Zero();
    double query_extra = -1.0, query_disp = 0.0;
    std::uint64_t query_refits = 0;
  };
  bool covers(const Finger& F, const Vec3& centre, double motion) const;
  void ensure_candidates(int f, const Vec3& centre, double motion);
  void find_samples(int f, const cloth::ClothState& s, const Vec3& proxy_at);
  void make_spring(int f, const Sample& q, cloth::PointSpring& sp) const;
  bool place(Sample& q, const Vec3& x, const Vec3& p0, const Vec3& motion) const;
  bool slides(const Sample* before) const;
  void linearize_pressure(Sample& q) const;
  void decide_friction(int f, Sample& q) const;
  void set_coupling_target(cloth::ProxyNode& P, const FingerTarget& device) const;
  void couple_through_fingertip(int f, cloth::ProxyNode& P);
  void limit_chain_force(cloth::ProxyNode& P) const;
  Vec3 expected_proxy(int f, bool first);
  void approach_refined_compliance(int f);
  double normal_at_end(const Sample& q, const Vec3& rel_step) const;
  bool add_contacts(int f, const std::vector<Vec3>& x_new, const Vec3& p0, const Vec3& p1);
  bool restore_touching(int f, const std::vector<Vec3>& x_new, const Vec3& dp);
  void merge_added(Finger& F, size_t nold);
  void rejoin(Sample& q, const Vec3& rel) const;
  double revise_friction(Sample& q, const Vec3& p0, const Vec3& rel_step, bool defer) const;
  template <class Fn>
  void for_samples_near(int t, const std::vector<Vec3>& x, const Vec3& c, double R, Fn&& fn) const;
  Vec3 point(const std::vector<Vec3>& x, int tri, const double b[3]) const;
  void nearest_surface(int f, const cloth::ClothState& s, const Vec3& c, ProxyResult& r) const;
  void rebuild_springs();

  const cloth::ClothModel& model_;
  const std::vector<std::array<int, 3>>& tris_;
  int fingers_;
  ContactParams p_;
  cloth::Integrator& integ_;
  BroadPhase bp_;
  const ContactStepRules& steps_;  // what the step's length changes (contact_steps.hpp)
  double spacing_;
  std::vector<int> sub_, first_;  // per triangle: subdivisions, first sample id
  std::array<Finger, kMaxFingers> fing_;
  std::vector<Sample> merged_;  // merge_added()'s buffer
  std::array<ProxyResult, kMaxFingers> out_{};
  std::array<double, kMaxFingers> refined_c_{};  // m/N, in series with the coupling
  std::array<double, kMaxFingers> refined_target_{};  // m/N, the refinement's latest
  std::array<Vec3, kMaxFingers> refined_push_{};      // its direction, unit (zero: the step's normal)
  std::array<Vec3, kMaxFingers> last_disp_{};    // the proxy's displacement in the last step
  std::array<Vec3, kMaxFingers> last_target_{};  // the coupling's target in the last step
  std::array<Vec3, kMaxFingers> device_target_{};  // this step's device target (set_coupling_target)
  std::array<Vec3, kMaxFingers> refined_axis_{};  // the refined compliance's axis this step (direct coupling)
  std::array<Vec3, kMaxFingers> tip_{};  // the fingertip at the end of the last step (result().proxy)
  std::array<Vec3, kMaxFingers> p0_{};  // proxies at the start of the step
  std::array<bool, kMaxFingers> seen_{}, valid_{};  // present since the last absence / this step
  const cloth::ClothState* s0_ = nullptr;          // the state the step started from
  double h_ = 1e-3;
  int revisions_ = 0;  // revise() calls in this step
  double vmax_ = 0.0;  // fastest vertex at the start of the step, m/s
  double max_pen_ = 0.0;
  std::uint64_t samples_in_contact_ = 0;
};

}  // namespace hapticloth::haptics
