// Local refinement (section 4.2): around a fingertip, a patch of the global mesh subdivided
// once (each triangle into four, masses redistributed by area) and simulated at the haptic rate
// with a spring-mass model, so that the surface under the finger moves smoothly between global
// steps. Border vertices follow the global simulation at constant velocity between its steps;
// interior vertices carry their own state across global updates, so the force the user feels
// does not jump when a slow global simulation updates. The contact spring acts on the patch at
// every substep. Storage is fixed at construction: rebuilding and stepping allocate nothing.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "haptics/contact/geometry.hpp"
#include "haptics/sim/handoff.hpp"

namespace hapticloth::haptics {

struct PatchParams {
  double radius = 0.0;         ///< m: global triangles with a corner this close to the finger
                               ///< (0: the session picks it from the mesh)
  double stiffness = 2000.0;   ///< N/m: membrane modulus of the spring model (set from the law)
  double areal_density = 0.3;  ///< kg/m^2
  double damping = 300.0;      ///< 1/s: interior velocity damped towards the global cloth's (the
                               ///< spring network has no bending: this keeps it from crumpling)
  double contact_damping = 1.0;  ///< N s/m on the touched point's normal motion in the patch
  int substeps = 32;           ///< per haptic tick, at least (explicit integration: stable for
                               ///< omega h < 2; more are taken when the springs need them)
  int max_substeps = 256;      ///< per haptic tick, at most: a stiffer patch has its springs
                               ///< softened to what this many substeps integrate stably
  double contact_stiffness = 2000.0;  ///< N/m, the fingertip spring (for the stability bound)
  int max_triangles = 192;     ///< global triangles per patch (4x as many refined ones)
  double haptic_period = 1e-3;  ///< s, one step() (the scene's haptic rate)
};

/// The fingertip on the patch for one tick: centre c (velocity vc), radius r, on side `side` of
/// the surface, touching refined triangle `tri` at barycentric `b` while `contact`, with the
/// contact spring k and Coulomb coefficient mu.
struct PatchTouch {
  bool contact = false;
  Vec3 c = Vec3::Zero(), vc = Vec3::Zero();
  double r = 0.0, k = 0.0, mu = 0.0;
  int side = 0, tri = -1;
  double b[3] = {1, 0, 0};
};

/// What the finger touches on the patch.
struct SurfacePoint {
  Vec3 point, normal, velocity;
  int triangle = -1;  ///< refined triangle
  double bary[3];
  double dist2 = 1e300;
};

class LocalPatch {
 public:
  LocalPatch(const std::vector<std::array<int, 3>>& global_tris,
             const std::vector<Vec3>& rest_positions, const std::vector<char>& pinned,
             const PatchParams& p);

  bool active() const { return nt_ > 0; }
  const Vec3& centre() const { return centre_; }
  double params_radius() const { return p_.radius; }
  /// Substeps per tick of the current build, and the factor its springs were softened by to
  /// stay stable within max_substeps (1: not softened).
  int substeps() const { return substeps_; }
  double spring_scale() const { return spring_scale_; }
  int triangles() const { return nt_; }
  int vertices() const { return nv_; }
  /// Patch vertex v follows the global cloth (on the patch's boundary, or pinned).
  bool border(int v) const { return border_[v] != 0; }
  /// Builds the patch around `c` from snapshot `s` (interior state from the snapshot), from
  /// the triangles the snapshot lists for `finger` (ClothSnapshot::near_triangles): its cost
  /// grows with the patch, not with the mesh.
  void rebuild(const ClothSnapshot& s, int finger, const Vec3& c) noexcept;
  void clear() noexcept { nt_ = nv_ = 0; }
  /// Advances the patch by one haptic period to loop time `now`. While touching, on every
  /// substep the normal spring and the Coulomb friction spring to `anchor` (carried by the
  /// touched point, sliding when beyond mu x normal force) act on the patch, so the coupling is
  /// stable for the light refined vertices. Returns the force on the user's finger averaged over
  /// the substeps; `slipping` tells whether the friction slid.
  Vec3 step(const ClothSnapshot& s, double now, const PatchTouch& t, Vec3& anchor,
            bool& slipping) noexcept;
  /// Closest point of the patch surface to p, with shaded normal and velocity.
  SurfacePoint closest(const Vec3& p) const noexcept;
  /// The global triangle a refined triangle came from.
  int global_triangle(int refined) const { return sel_[refined / 4]; }

 private:
  // The contact kernel of a tick: the touched point q0 and its normal n0 at the start of the
  // tick, over n vertices (kernel_vertex_, kernel_weight_, x0_).
  struct Kernel {
    int n = 0;
    Vec3 q0 = Vec3::Zero(), n0 = Vec3::UnitZ();
  };
  // rebuild()
  int select(const ClothSnapshot& s, int finger, const Vec3& c) noexcept;
  int patch_vertex(int a, int b) noexcept;
  int refined_edge(int i, int j) noexcept;
  void subdivide(int ns) noexcept;
  void springs() noexcept;
  void mark_border(int ns) noexcept;
  void stable_substeps() noexcept;
  // step()
  void border_positions(const ClothSnapshot& s, double now) noexcept;
  Kernel contact_kernel(const PatchTouch& touch) noexcept;
  void spring_forces() noexcept;
  Vec3 contact_forces(const PatchTouch& touch, const Kernel& K, Vec3& anchor, Vec3& q_prev,
                      bool& slipping) noexcept;
  void integrate(const ClothSnapshot& s, double h) noexcept;
  void normals() noexcept;

  const std::vector<std::array<int, 3>>& gt_;
  const std::vector<Vec3>& rest_;
  const std::vector<char>& pinned_;
  PatchParams p_;
  Vec3 centre_ = Vec3::Zero();
  int nt_ = 0, nv_ = 0, ne_ = 0;
  // Patch vertices: either a global vertex (a = b) or the midpoint of global edge (a, b): edge_end_a_, edge_end_b_.
  std::vector<int> edge_end_a_, edge_end_b_;
  std::vector<char> border_;
  std::vector<Vec3> x_, v_, n_, f_;
  std::vector<double> m_;
  std::vector<std::array<int, 3>> tri_;
  std::vector<std::array<int, 2>> edge_;
  std::vector<double> rest_len_, k_;
  std::vector<int> sel_;                    // selected global triangles
  std::vector<std::array<int, 3>> key_;     // hash table (edge end a, edge end b, patch vertex)
  std::vector<std::array<int, 3>> edge_key_;  // hash table (i, j, refined edge)
  std::vector<int> uses_;                   // per midpoint vertex: selected triangles on its edge
  double edge_mean_ = 0.0;
  int substeps_ = 32;                       // this build's substeps per tick
  double spring_scale_ = 1.0;               // < 1: springs softened for stability
  std::vector<double> vertex_stiffness_;                  // per vertex: sum of its springs' stiffness
  std::vector<int> kernel_vertex_;                     // contact kernel: vertices, weights, start positions
  std::vector<double> kernel_weight_;
  std::vector<Vec3> x0_;
};

}  // namespace hapticloth::haptics
