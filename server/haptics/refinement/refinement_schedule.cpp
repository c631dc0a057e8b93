#include "haptics/refinement/refinement_schedule.hpp"

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

namespace hapticloth::haptics {

void InlineRefinement::after_step(const cloth::ClothState& s, FingertipContact& contact, int fingers) {
  in_.take(s, contact, fingers);
  r_->update(in_);
  ++updates_;
  regions_.gather(*r_, fingers, updates_);
  for (int f = 0; f < fingers; ++f) contact.set_refined_compliance(f, r_->series(f));
}

BackgroundRefinement::BackgroundRefinement(std::unique_ptr<LocalRefinement> r)
    : r_(std::move(r)), worker_([this] { work(); }) {}

BackgroundRefinement::~BackgroundRefinement() {
  {
    std::lock_guard<std::mutex> lock(m_);
    stop_ = true;
  }
  cv_.notify_one();
  worker_.join();
}

// The step hands over its input (replacing one the worker has not taken: only the latest
// matters) and takes the compliances the worker last settled. A finger out of contact in this
// step gets none at once: the compliance of a touch that ended must not stiffen the next.
void BackgroundRefinement::after_step(const cloth::ClothState& s, FingertipContact& contact, int fingers) {
  std::array<SeriesCompliance, kMaxFingers> c{};
  {
    std::lock_guard<std::mutex> lock(m_);
    skipped_.fetch_add(has_pending_ ? 1 : 0, std::memory_order_relaxed);
    pending_.take(s, contact, fingers);
    has_pending_ = true;
    c = compliance_;
    if (regions_ready_) std::swap(ready_, regions_);  // storage swapped, not copied
    regions_ready_ = false;
  }
  cv_.notify_one();
  for (int f = 0; f < fingers; ++f)
    contact.set_refined_compliance(f, contact.result(f).in_contact ? c[f] : SeriesCompliance{});
}

void BackgroundRefinement::work() {
  setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), 10);  // below the simulation
  for (;;) {
    {
      std::unique_lock<std::mutex> lock(m_);
      cv_.wait(lock, [&] { return has_pending_ || stop_; });
      if (stop_) return;
      std::swap(pending_, working_);  // vectors swapped, not copied: no allocation
      has_pending_ = false;
    }
    r_->update(working_);
    gathered_.gather(*r_, working_.fingers, updates_.load(std::memory_order_relaxed) + 1);
    std::lock_guard<std::mutex> lock(m_);
    for (int f = 0; f < working_.fingers; ++f) compliance_[f] = r_->series(f);
    std::swap(gathered_, ready_);
    regions_ready_ = true;
    builds_.store(r_->builds(), std::memory_order_relaxed);
    updates_.fetch_add(1, std::memory_order_relaxed);
  }
}

}  // namespace hapticloth::haptics
