// When the refined children under the fingertips (LocalRefinement) are settled: within the
// global step that produced their input (InlineRefinement: deterministic, what the stepped
// sessions and the tests run), or beside the steps on a worker thread (BackgroundRefinement:
// what a real-time session runs). A child's settle takes 0.3-1.3 ms and a fresh child's several
// (docs/contact.md, 'Local refinement under the fingertips'), more than direct coupling's 1 ms
// step has beside the cloth; beside the steps it costs the step a copy of the cloth's
// positions, and the compliance a step puts in series with the coupling is the one the worker
// last settled (a few steps old: the compliance follows the contact patch, which changes over
// tens of ms).
#pragma once

#include <array>
#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <thread>

#include "haptics/contact/fingertip_contact.hpp"
#include "haptics/refinement/local_refinement.hpp"
#include "haptics/refinement/refined_regions.hpp"

namespace hapticloth::haptics {

class RefinementSchedule {
 public:
  virtual ~RefinementSchedule() = default;
  /// After a global step: the children take its cloth `s` and `contact`'s fingertips; the
  /// compliances for the next step are set on `contact`.
  virtual void after_step(const cloth::ClothState& s, FingertipContact& contact, int fingers) = 0;
  /// Children built so far, and refinement updates done (each settles every touching child).
  virtual std::uint64_t builds() const = 0;
  virtual std::uint64_t updates() const = 0;
  /// The updates run beside the steps (BackgroundRefinement), not within them.
  virtual bool beside_steps() const = 0;
  /// The children as of the last update this thread has seen (a viewer's: cloth_state_t).
  const RefinedRegions& regions() const { return regions_; }

 protected:
  RefinedRegions regions_;  // the simulation thread's
};

class InlineRefinement final : public RefinementSchedule {
 public:
  explicit InlineRefinement(std::unique_ptr<LocalRefinement> r) : r_(std::move(r)) {}
  void after_step(const cloth::ClothState& s, FingertipContact& contact, int fingers) override;
  std::uint64_t builds() const override { return r_->builds(); }
  std::uint64_t updates() const override { return updates_; }
  bool beside_steps() const override { return false; }

 private:
  std::unique_ptr<LocalRefinement> r_;
  RefinementInput in_;
  std::uint64_t updates_ = 0;
};

class BackgroundRefinement final : public RefinementSchedule {
 public:
  /// Starts the worker thread (at a lower priority than the simulation's: nice 10).
  explicit BackgroundRefinement(std::unique_ptr<LocalRefinement> r);
  ~BackgroundRefinement() override;
  void after_step(const cloth::ClothState& s, FingertipContact& contact, int fingers) override;
  std::uint64_t builds() const override { return builds_.load(std::memory_order_relaxed); }
  std::uint64_t updates() const override { return updates_.load(std::memory_order_relaxed); }
  bool beside_steps() const override { return true; }
  /// Steps whose input replaced one the worker had not taken yet.
  std::uint64_t skipped() const { return skipped_.load(std::memory_order_relaxed); }

 private:
  void work();

  std::unique_ptr<LocalRefinement> r_;  // the worker's alone once it runs
  std::mutex m_;
  std::condition_variable cv_;
  RefinementInput pending_, working_;     // the next input (under m_), the worker's
  bool has_pending_ = false, stop_ = false;
  std::array<SeriesCompliance, kMaxFingers> compliance_{};  // the worker's last (under m_)
  RefinedRegions gathered_, ready_;               // the worker's; its last, for the step (under m_)
  bool regions_ready_ = false;                    // under m_
  std::atomic<std::uint64_t> builds_{0}, updates_{0}, skipped_{0};
  std::thread worker_;
};

}  // namespace hapticloth::haptics
