// Generalized semi-implicit Euler integration (section 3.3.3, eqs. 8-9) with blow-up recovery.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "cloth/element_pass.hpp"
#include "cloth/element_partition.hpp"
#include "cloth/kept_matrix.hpp"
#include "cloth/model.hpp"
#include "cloth/solver.hpp"
#include "cloth/worker_pool.hpp"

namespace hapticloth::cloth {

/// What a step's contacts (StepContacts) are: Short, the steps of direct coupling, one per haptic
/// tick (their contacts are revised on local settles, confirmed by a whole solve, and their
/// friction corrections wait a step); Long, the multirate path's global steps of 5-40 ms (each
/// re-solve is whole, and the step keeps revising until its contacts hold). The rendering mode
/// chooses (haptics::Rendering), not the step's length.
enum class ContactSteps { Short, Long };

struct IntegratorConfig {
  double dt = 1e-3;     ///< s
  double alpha = 1.0;   ///< implicitness, in [0.5, 1] (eq. 8): 1 backward Euler, 0.5 midpoint
  Vec3 gravity{0.0, 0.0, -9.81};  ///< m/s^2
  double air_damping = 0.0;       ///< linear air drag per area, N s / m^3 (force -c a v)
  JacobianMode jacobian = JacobianMode::Spd;
  int max_halvings = 4;           ///< retries a failed step with dt/2, dt/4, ... this deep
  double explosion_ratio = 1.0;   ///< energy gain per step, relative to the energy scale,
                                  ///< above which a step is an energy explosion
  int proxies = 0;                ///< massless proxy nodes solved with the cloth (fingertips)
  ContactSteps contact_steps = ContactSteps::Short;  ///< with proxies
  int max_contact_revisions = 16; ///< re-solves of a step whose contact set changed
  /// Threads of the element assembly and the PCG's sweeps: 1, or 2 (a helper thread shares
  /// them with the stepping thread; meshes under kMinParallelElements stay on one).
  int assembly_threads = 1;
  /// The matrix is kept from step to step (KeptMatrix): an element's blocks are formed anew when
  /// its factored Jacobian has moved by more than this fraction of its largest entry since they
  /// were last formed; 0 forms every block every step. Forces and the right-hand side are exact
  /// either way.
  double matrix_refresh = 1e-4;
  /// The instruction level of the element pass (simd_level.hpp); none: the widest this CPU runs.
  std::optional<SimdLevel> simd = std::nullopt;
  /// The level the element pass runs at: `simd`, or the widest this CPU runs.
  SimdLevel element_level() const { return simd ? *simd : best_level(); }

  /// Throws std::invalid_argument naming the offending field.
  void validate() const;
};

/// Counted, named blow-up events (never silent).
struct IntegratorEvents {
  std::uint64_t non_finite = 0;           ///< NaN or infinity in forces, solution or state
  std::uint64_t solver_not_converged = 0; ///< iterative solver hit its iteration limit
  std::uint64_t solver_error = 0;         ///< numerical failure inside the solver
  std::uint64_t not_positive_definite = 0;
  std::uint64_t jacobian_fallbacks = 0;   ///< exact Jacobian indefinite: re-solved with Spd
  std::uint64_t energy_explosions = 0;
  std::uint64_t alpha_fallbacks = 0;      ///< explosions at alpha < 1 after which alpha is 1
  std::uint64_t retries = 0;              ///< failed (sub)steps retried at half the step
  std::uint64_t restores = 0;             ///< steps abandoned: last good state restored, at rest
  std::uint64_t contact_revisions = 0;    ///< solves repeated because the contact set changed
  std::uint64_t contact_line_cuts = 0;    ///< re-solves the line search took only part of
  std::uint64_t contact_settles = 0;      ///< of the re-solves, those that settled the contacts' rows alone
  std::uint64_t contact_confirmations = 0;  ///< whole solves after settles (not re-solves)
  std::uint64_t total() const {
    return non_finite + solver_not_converged + solver_error + not_positive_definite +
           jacobian_fallbacks + energy_explosions + alpha_fallbacks + retries + restores;
  }
};

/// A massless proxy node solved with the cloth in eq. 9 (a fingertip in constraint-based haptic
/// rendering): a spring-damper holds it to a target (the device's fingertip at the end of the
/// step), point springs (contacts) push it. Being massless it is in force balance at the end of
/// every step, so the force its coupling spring renders is exactly minus the sum of the forces
/// it puts on the cloth (Newton's third law).
struct ProxyNode {
  Vec3 x = Vec3::Zero();                ///< position, m (moved by each step)
  Vec3 target = Vec3::Zero();           ///< where the coupling pulls it at the end of the step, m
  Vec3 target_velocity = Vec3::Zero();  ///< m/s, for the coupling's damping
  double stiffness = 0.0;               ///< N/m of the coupling
  double damping = 0.0;                 ///< N s/m of the coupling
  /// Along the unit `axis` the coupling's stiffness is `axis_stiffness` instead (0: isotropic):
  /// a local refinement's compliance acts along the contact's normal only.
  Vec3 axis = Vec3::Zero();
  double axis_stiffness = 0.0;
  /// The coupling's stiffness matrix, N/m: k I + (k_axis - k) a a^T.
  Mat3 stiffness_matrix() const {
    Mat3 K = stiffness * Mat3::Identity();
    if (axis_stiffness > 0.0) K += (axis_stiffness - stiffness) * axis * axis.transpose();
    return K;
  }
  Vec3 displacement = Vec3::Zero();     ///< out: its motion over the last step, m
};

/// A force between a material point of the cloth (weights b on the corners of triangle `tri`)
/// and a proxy: f on the cloth at the start of the step (the proxy gets -f) and its stiffness
/// K = -df/dx_point = df/dx_proxy (symmetric PSD), which enters eq. 9 like H.
///
/// A contact's spring is one-sided along its normal (`kn` > 0): of f and K, the part
/// kn (depth0 - n . r) n, kn n n^T is a penalty that acts only while the point is inside
/// (r: the point's displacement over the step relative to the proxy's). The rest (friction) acts
/// whole. The active-set line search (Integrator::revise_contacts) uses it; `key` names the
/// contact, and a contact owner lists its springs in ascending (proxy, key).
struct PointSpring {
  int tri = 0;
  double b[3] = {0, 0, 0};
  int proxy = 0;
  Vec3 f = Vec3::Zero();
  Mat3 K = Mat3::Zero();
  int key = -1;         ///< the contact's identity (>= 0 for a one-sided contact)
  double kn = 0.0;      ///< N/m, normal penalty stiffness; 0: a two-sided spring
  double depth0 = 0.0;  ///< m, depth along n at the start of the step
  Vec3 n = Vec3::Zero();
};

/// The contact set's owner: after each solve of a (sub)step it sees the candidate end state and
/// may change the point springs (a contact that would pull, a point that would go through), in
/// which case the step is solved again with them (an active-set iteration).
class StepContacts {
 public:
  virtual ~StepContacts() = default;
  /// `x_new`: candidate end positions of all vertices; proxies hold their candidate
  /// displacement. `short_of_solve`: the candidate is the active-set line search's point, short
  /// of the last re-solve, where a released contact touches again (Integrator::revise_contacts).
  /// `same_candidate`: the last re-solve left the solution as it was (a PCG that took no
  /// iteration), so this is the candidate the last call saw. Returns true if the springs (Integrator::point_springs) changed.
  virtual bool revise(const std::vector<Vec3>& x_new, const std::vector<ProxyNode>& proxies,
                      bool short_of_solve, bool same_candidate) = 0;
};

struct StepTiming {
  double assemble_ms = 0, solve_ms = 0, total_ms = 0;
  /// Of total_ms, the stepping thread's waits for the helper thread (assembly_threads 2) to
  /// finish its share of a run.
  double helper_wait_ms = 0;
  int iterations = 0;  ///< solver iterations summed over substeps
  int substeps = 0;    ///< 1 unless the step was split after a failure
  /// Elements whose blocks were formed anew, summed over the assemblies (all of them in an
  /// assembly formed whole; IntegratorConfig::matrix_refresh).
  int refreshed_elements = 0;
  /// Assemblies that formed the matrix whole (the others kept it).
  int whole_assemblies = 0;
  /// Block rows the solver reloaded for a kept matrix's first solve (-1: it loaded them all).
  int changed_rows = -1;
};

enum class StepOutcome { Accepted, Restored };

/// Below this many elements the assembly stays on one thread: waking the helper costs about
/// what it saves.
inline constexpr int kMinParallelElements = 2000;

class Integrator {
 public:
  /// The model must outlive the integrator. Allocates all working memory here.
  Integrator(const ClothModel& model, const IntegratorConfig& config,
             std::unique_ptr<LinearSolver> solver);

  /// Advances the state by config.dt with eq. 9:
  ///   (M + alpha h C + alpha^2 h^2 H) dv = h (F - alpha h H v),   dx = h (v + alpha dv)
  /// with H = -dF/dP and C = -dF/dP'. Pinned vertices move with their own velocity.
  /// A failed step is retried with halved steps, and if that fails the state at the start of
  /// the step is restored with zero velocity. Allocation-free after the first call.
  StepOutcome step(ClothState& s);

  /// External forces (N) per vertex, applied on every step until changed. Sized to vertices.
  std::vector<Vec3>& external_forces() { return f_ext_; }
  /// Stiffness of the external forces (N/m per vertex, -d f_ext / d x, symmetric PSD), so that a
  /// stiff contact spring enters the solve implicitly. Zero by default; set
  /// `external_stiffness_on` when any is non-zero (skipped otherwise).
  std::vector<Mat3>& external_stiffness() { return k_ext_; }
  bool external_stiffness_on = false;

  /// Proxy nodes (config.proxies of them) and the point springs between them and the cloth,
  /// both set by the caller before each step (capacity is the caller's: reserve it).
  std::vector<ProxyNode>& proxies() { return proxies_; }
  const std::vector<ProxyNode>& proxies() const { return proxies_; }
  std::vector<PointSpring>& point_springs() { return springs_; }
  /// The contact set's owner; reserve point_springs() first: the re-solves' copies of the set
  /// are sized to it here, so they allocate nothing on the step.
  void set_contacts(StepContacts* c) {
    contacts_ = c;
    springs_solved_.reserve(springs_.capacity());
    springs_in_matrix_.reserve(springs_.capacity());
    released_.reserve(springs_.capacity());
  }

  /// The proxies' response over the last accepted step, R_pq = h (alpha h k_q + c_q) [A^-1]_pq
  /// with the step's own matrix (eq. 9, the contacts as solved; a re-solve with the factor or
  /// preconditioner the step left). The coupling force on finger p, F_p = k_p (x_p - T_p) +
  /// c_p (v_p - V_p), then moves with the targets T_q and their velocities V_q as
  ///   dF_p / dT_q = k_p (R_pq - delta_pq I),   dF_p / dV_q = c_p (R_pq - delta_pq I),
  /// and the proxy's end position as dx_p / dT_q = R_pq alpha h k_q / (alpha h k_q + c_q).
  /// The multirate path renders the fingertips from it between global steps. `R` gets
  /// proxies^2 blocks, row-major (R[p * proxies + q]). False if a solve failed. Allocates on
  /// its first call only.
  bool proxy_response(std::vector<Mat3>& R);

  /// Keeps the helper thread of the assembly and the PCG (assembly_threads 2) awake while the
  /// guard lives: a caller that has work of its own right before step() (the contact search)
  /// hides the helper's wake-up behind it. No effect on one thread.
  WorkerPool::Burst keep_helper_awake() { return WorkerPool::Burst(pool_.get()); }

  const IntegratorEvents& events() const { return events_; }
  const StepTiming& last_timing() const { return timing_; }
  /// The element pass's instruction level and the doubles in its lanes.
  SimdLevel simd_level() const { return simd_; }
  int lanes() const { return lanes_; }
  const IntegratorConfig& config() const { return cfg_; }
  const LinearSolver& solver() const { return *solver_; }
  const ClothModel& model() const { return model_; }

  /// The system matrix of eq. 9 at state s for step h (for tests and analysis).
  const SymCsr& system_matrix(const ClothState& s, double h, JacobianMode mode);
  /// The matrix of the last step's solves as it stands, formed whole or kept (for tests and
  /// analysis).
  const SymCsr& matrix() const { return A_; }
  /// The right-hand side of eq. 9 from the last assembly (free-vertex order, 3 per vertex).
  const Eigen::VectorXd& system_rhs() const { return rhs_; }

 private:
  enum class Attempt { Ok, Failed };
  Attempt advance(ClothState& s, double h, int depth);
  Attempt single_step(ClothState& s, double h);
  bool slow_blow_up(double h);
  double weight_impulse(double h) const;
  bool solve(const ClothState& s, double h);
  bool revise_contacts(const ClothState& s, double h);
  bool confirm_settled(const ClothState& s, double h, bool& same);
  bool account_resolve(SolveStatus st, std::chrono::steady_clock::time_point t0, bool& same);
  bool resolved(SolveStatus st);
  bool line_search_contacts(const ClothState& s, double h);
  double spring_depth(const PointSpring& sp, const ClothState& s, double h,
                      const Eigen::VectorXd& dv) const;
  bool energy_explosion(const ClothState& s, double& work);
  void accept(ClothState& s, double h, double work);
  bool assemble(const ClothState& s, double h, JacobianMode mode);
  void assemble_proxies(const ClothState& s, double h);
  void add_springs(const ClothState& s, double h, const std::vector<PointSpring>& springs,
                   double sign);
  void mark_spring_rows(const std::vector<PointSpring>& springs);
  template <class F>
  void for_each_spring_row(const std::vector<PointSpring>& springs, F&& f) const;
  void candidate_state(const ClothState& s, double h);
  double contact_work(const ClothState& s) const;
  struct ClothEnergy {
    double elastic = 0.0, kinetic = 0.0, gravity = 0.0;  // J
  };
  // Form: WholeMatrix or KeptChanges (kept_matrix.hpp), how this assembly forms the matrix.
  template <class Form>
  bool assemble_as(const ClothState& s, double h, JacobianMode mode);
  template <class Form>
  ClothEnergy assemble_cloth(const ClothState& s, double h, bool spd);
  template <class Form>
  ClothEnergy vertex_terms(const ClothState& s, double h, int part);
  template <class Form>
  void clear_rows(const std::vector<std::pair<int, int>>& spans);
  void take_out_springs(double h);
  void mark_proxy_rows();
  void plan_clearing(const ElementPartition& partition);
  bool state_finite(const ClothState& s) const;

  const ClothModel& model_;
  IntegratorConfig cfg_;
  std::unique_ptr<LinearSolver> solver_;
  IntegratorEvents events_;
  StepTiming timing_;
  bool viscous_;
  double energy_floor_;

  SystemPattern sys_;
  SymCsr A_;
  std::vector<ProxyNode> proxies_;
  std::vector<PointSpring> springs_, springs_solved_;  // solved_: the set a re-solve replaces
  std::vector<PointSpring> springs_in_matrix_;  // the set whose terms A_ holds (KeptMatrix)
  std::vector<int> spring_rows_;         // block rows a re-solve's spring change touches
  std::vector<char> spring_row_marked_;  // per block row: in spring_rows_
  StepContacts* contacts_ = nullptr;
  Eigen::VectorXd rhs_, dv_, dv_prev_, guess_;  // dv_prev_: the solution before dv_
  // line_search_contacts(): the segment's start and end, its direction, A times it
  Eigen::VectorXd dv_from_, dv_full_, delta_, a_delta_;
  struct DepthTerm {  // a one-sided contact along the line search: depth(t) = d + t dd
    double kn, d, dd;
    bool in_set;  // in the re-solved set (its linear spring is in the matrix) or released
  };
  std::vector<DepthTerm> ls_terms_;
  std::vector<PointSpring> released_;  // contacts released by this step's re-solves, not back
  std::vector<Vec3> f_ext_;
  std::vector<Mat3> k_ext_;
  std::vector<Mat3> k_ext_in_matrix_;  // the external stiffness A_ holds (KeptMatrix)
  bool k_ext_held_ = false;            // whether A_ holds any
  // The kept matrix: its factors, and the rows changed since the solver's copy was A_.
  std::unique_ptr<KeptMatrix> kept_;
  bool assembled_kept_ = false;  // the last assembly kept the matrix
  bool solver_synced_ = false;   // the solver's copy is A_ but for the rows kept_ marked
  std::vector<int> part_refreshed_;  // per assembly part (and the rest): elements formed anew
  std::vector<Vec3> xn_, vn_;              // candidate state of a (sub)step
  std::vector<Vec3> x_start_, v_start_;    // state at the start of step()
  double energy_old_ = 0.0, energy_scale_ = 0.0;
  double excess_energy_ = 0.0, pending_excess_ = 0.0;  // energy created beyond the external work, 0.1 s memory
  double prev_energy_ = 0.0, last_work_ = 0.0;  // total energy and work of the last accepted step
  bool have_prev_energy_ = false;
  std::vector<Vec3> x_before_;   // positions at the start of the previous step
  bool have_before_ = false, blown_up_ = false;
  double alpha_ = 1.0;  // alpha in use: cfg_.alpha, or 1 from the first explosion on
  double last_h_ = 0.0; // the last (sub)step solved
  double free_mass_norm_ = 0.0;  // |m| over the free vertices, kg (weight_impulse)
  std::vector<Eigen::VectorXd> response_;  // proxy_response(): A^-1 e per proxy dof (warm starts)
  Eigen::VectorXd unit_;
  // The element pass (assemble_cloth) at the instruction level in use: all the elements as one
  // part, or with two threads (assembly_threads 2) the parts and, last, the separators; the
  // parts' energies.
  std::unique_ptr<ElementPass> pass_;
  SimdLevel simd_ = SimdLevel::Baseline;
  int lanes_ = 0;
  std::vector<ClothEnergy> part_energy_;
  std::vector<std::vector<std::pair<int, int>>> zero_spans_;  // plan_clearing
  std::vector<std::vector<int>> part_free_;  // plan_clearing; on one thread all, as one "rest"
  std::unique_ptr<WorkerPool> pool_;
};

}  // namespace hapticloth::cloth
