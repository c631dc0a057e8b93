// The simulation halves of the modes that solve the fingertip proxies with the cloth
// (rendering.hpp). ProxyCoupling (direct coupling): each step takes the device's fingertips as
// the proxies' coupling targets and the contacts FingertipContact finds, and after it the
// refinement under the fingertips (LocalRefinement) measures the compliance the global mesh
// lacks for the next step. ResponseCoupling (the multirate path's response model) also hands
// the haptic loop the step's linear response to the fingertips (cloth::Integrator::
// proxy_response), which it renders from until the next step.
#pragma once

#include <memory>
#include <vector>

#include "haptics/contact/fingertip_contact.hpp"
#include "haptics/refinement/local_refinement.hpp"
#include "haptics/modes/params.hpp"
#include "haptics/refinement/refinement_schedule.hpp"
#include "haptics/modes/sim_coupling.hpp"

namespace hapticloth::haptics {

class ProxyCoupling : public SimCoupling {
 public:
  /// `refine`: whether the mode refines (where the mesh needs it).
  ProxyCoupling(const cloth::ClothModel& model, cloth::Integrator& integ, int fingers,
                const FingerParams& finger, const CouplingParams& coupling, bool refine);

  void couple(const HapticReport& r, double now, cloth::ClothState& s) override;
  void conclude(const cloth::ClothState& s) override;
  void fill(const HapticReport& r, const cloth::ClothState& s, ClothSnapshot& snap) override;
  const FingertipContact* fingertips() const override { return &tips_; }
  const RefinementSchedule* refinement() const override { return refine_.get(); }
  void refine_beside_steps() override;

 protected:
  cloth::Integrator& integ_;
  int fingers_;

 private:
  std::array<FingerTarget, kMaxFingers> targets(const HapticReport& r, double now) const;

  std::unique_ptr<LocalRefinement> make_refinement() const;

  const cloth::ClothModel& model_;
  FingerParams finger_;
  CouplingParams coupling_;
  FingertipContact tips_;
  std::unique_ptr<RefinementSchedule> refine_;
};

class ResponseCoupling final : public ProxyCoupling {
 public:
  using ProxyCoupling::ProxyCoupling;
  void conclude(const cloth::ClothState& s) override;
  void fill(const HapticReport& r, const cloth::ClothState& s, ClothSnapshot& snap) override;

 private:
  bool has_response_ = false;
  std::vector<cloth::Mat3> response_;
};

/// The scene's fingertip as the contact model sees it.
ContactParams contact_params(const FingerParams& f, double margin);

}  // namespace hapticloth::haptics
