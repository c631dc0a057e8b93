// The multirate path's response model (LocalModel::Response): the fingertip proxies are solved
// with the whole cloth at the global step (direct coupling's contact, FingertipContact), and
// the step hands over its linear response to the fingertips (cloth::Integrator::
// proxy_response). Between global steps, at the haptic rate, each finger's force follows both
// fingertips through it:
//   F_p = F_p* + sum_q (R_pq - delta_pq I) (k dT_q + c dV_q)
// where * is the step's solution and dT_q, dV_q the fingertips' motion since the targets the
// step used. This is W = J A^-1 J^T of constraint-based rendering of deformable bodies with the
// step's own matrix: the whole cloth's compliance at the contacts, both fingers together, so a
// pinch grips one piece of cloth. Contact is one-sided (a finger whose force would pull is
// released) and the tangential force stays in the friction cone; a finger that was not in
// contact at the step is rendered free until the next step finds its contact (docs/contact.md).
// The linear model is exact for a linear cloth; where the contact is not (a coarse mesh's
// facets, a patch that grows), a new step's model differs from the old one's prediction, and
// that difference is faded out over the next global step rather than felt as a step (the
// force interpolation of multirate rendering, Cavusoglu and Tendick 2000).
#pragma once

#include <array>
#include <cstdint>

#include "haptics/modes/surface_contact.hpp"

namespace hapticloth::haptics {

class ResponseContact final : public SurfaceContact {
 public:
  /// k, c: the coupling (N/m, N s/m); mu: Coulomb's coefficient (the cone of a finger's force).
  ResponseContact(double k, double c, double mu) : k_(k), c_(c), mu_(mu) {}
  void prepare(const ClothSnapshot& s, const std::array<Fingertip, kMaxFingers>& tips,
               const std::array<bool, kMaxFingers>& present, int fingers) noexcept override;
  void touch(const ClothSnapshot& s, double now, double tick_dt, const Fingertip& tip,
             FingerReport& out) noexcept override;
  void release(int finger) noexcept override;

 private:
  Vec3 faded(int f, double now) noexcept;
  Vec3 follow(const ClothSnapshot& s, const std::array<Fingertip, kMaxFingers>& tips,
              const std::array<bool, kMaxFingers>& present, int fingers, int p) const noexcept;
  Vec3 one_sided(const ProxyResult& r, const Vec3& F, bool& contact) const noexcept;

  double k_, c_, mu_;
  std::array<Vec3, kMaxFingers> force_{};   // this tick's model force (one-sided)
  std::array<bool, kMaxFingers> contact_{};
  std::array<Vec3, kMaxFingers> last_{};    // the force rendered on the last tick
  std::array<bool, kMaxFingers> last_contact_{};
  std::array<Vec3, kMaxFingers> offset_{};  // old model minus new at the update, fading out
  std::uint64_t step_ = 0;                  // the snapshot's step of the last tick
  double step_time_ = -1.0, fade_ = 0.0;    // its time, and the interval to fade over (s)
  double fade_start_ = 0.0;
  bool new_step_ = false;
};

}  // namespace hapticloth::haptics
