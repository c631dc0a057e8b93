// The session's report (session.hpp): its figures as text and as JSON.
#include "haptics/session.hpp"

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <iomanip>
#include <sstream>
#include <thread>

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <time.h>

#include <nlohmann/json.hpp>

#include "hal/cpu_latency.hpp"
#include "hal/device_clock.hpp"
#include "hal/mono_clock.hpp"
#include "hal/platform_timer.hpp"
#include "haptics/loop/deadlines.hpp"
#include "haptics/refinement/refinement_schedule.hpp"
#include "haptics/modes/rendering_modes.hpp"

namespace hapticloth::haptics {

SessionReport Session::report() const {
  SessionReport r = r_;
  r.sim_step_us = sim_->step_us();
  r.sim_helper_wait_us = sim_->helper_wait_us();
  r.sim_steps = sim_->steps();
  r.cloth_time = sim_->state().time - cloth_start_;
  r.contact_ticks = loop_->contact_ticks();
  r.out_of_reach_ticks = loop_->ticks_out_of_reach();
  r.patch_rebuilds = loop_->patch_rebuilds();
  r.patch_softened = loop_->patch_softened();
  r.patch_candidate_overflows = sim_->patch_candidate_overflows();
  r.device_errors = loop_->device_errors();
  r.late_ticks = loop_->late_ticks();
  r.tactile = tactile_note_;
  if (const TactileRendering* t = loop_->tactile()) {
    r.tactile_frames = t->counters().frames;
    r.tactile_textured = t->counters().textured_ticks;
    r.tactile_slips = t->counters().slip_ticks;
    r.tactile_clamped = gate_->counters().tactile_clamped + gate_->counters().tactile_non_finite;
  }
  r.passivity_ticks = loop_->passivity().stats().active_ticks;
  r.passivity_deficit = loop_->passivity().stats().deepest_deficit_j;
  if (const RefinementSchedule* rs = sim_->refinement()) {
    r.refinement_builds = rs->builds();
    r.refinement_updates = rs->updates();
    r.refinement_beside_steps = rs->beside_steps();
  }
  if (const EnergyBound* b = loop_->energy_bound()) {
    r.energy_bound_ticks = b->stats().limited_ticks;
    r.energy_withheld = b->stats().withheld_j;
  }
  if (const FingertipContact* c = sim_->fingertips()) {
    r.max_penetration = c->max_penetration();
    r.contact_samples = c->active_samples();
  }
  r.contact_revisions = sim_->integrator().events().contact_revisions;
  r.contact_line_cuts = sim_->integrator().events().contact_line_cuts;
  r.contact_settles = sim_->integrator().events().contact_settles;
  r.contact_confirmations = sim_->integrator().events().contact_confirmations;
  return r;
}

std::string SessionReport::to_text() const {
  std::ostringstream os;
  os.setf(std::ios::fixed);
  os.precision(1);
  auto h = [&](const char* name, const Histogram& x) {
    os << name << "p50 " << x.quantile(0.5) << ", p99 " << x.quantile(0.99) << ", p99.9 "
       << x.quantile(0.999) << ", max " << x.max() << " us\n";
  };
  // Overruns: ticks whose own compute took longer than the period, the loop's own lateness
  // (the kernel's late wake-ups skip ticks too, but never overrun one).
  os << "haptic ticks     " << haptic.ticks << " (" << missed_deadlines() << " missed deadlines), "
     << haptic.overruns << " of them overran their period\n";
  if (haptic.ticks > 0 && haptic.period_error_us.count() > 0) h("period error     ", haptic.period_error_us);
  if (haptic.compute_us.count() > 0) h("tick compute     ", haptic.compute_us);
  h("sim step         ", sim_step_us);
  if (sim_helper_wait_us.max() > 0.0) {
    h("  helper wait    ", sim_helper_wait_us);
    os << "  (steps waiting over 100 us: " << std::setprecision(3) << sim_helper_wait_us.fraction_at_least(100.0)
       << ")\n" << std::setprecision(1);
  }
  os << "sim steps        " << sim_steps << " in " << std::setprecision(3) << sim_time << " s: the cloth advanced "
     << cloth_time << " s (" << std::setprecision(2) << cloth_time_ratio() << " x the session's time)\n"
     << std::setprecision(1);
  os << "contact ticks    " << contact_ticks << " (slipping " << slip_ticks << "), max force "
     << max_force << " N\n";
  os << "out of reach     " << out_of_reach_ticks << " ticks (no fingertip within the broad-phase margin of the cloth)\n";
  os << "fingertip contact " << contact_samples << " sample-steps, " << contact_revisions
     << " re-solves (" << contact_settles << " settled locally, then " << contact_confirmations
     << " whole solves; " << contact_line_cuts << " cut short by the line search), deepest cloth point "
     << std::setprecision(3) << max_penetration * 1e3 << " mm inside a fingertip\n"
     << std::setprecision(1);
  if (patch_rebuilds > 0)
    os << "local patch      " << patch_rebuilds << " builds, " << patch_softened
       << " with springs softened to stay stable (material stiffer than max_substeps integrate), "
       << patch_candidate_overflows << " snapshots with more candidate triangles than room\n";
  os << "late ticks       " << late_ticks << " (their motion caught up over the ticks missed); "
     << "passivity control on " << passivity_ticks << " ticks, coupling's largest deficit "
     << std::setprecision(2) << passivity_deficit * 1e6 << " uJ\n" << std::setprecision(1);
  os << "tactile          " << tactile;
  if (tactile_frames > 0)
    os << "; " << tactile_frames << " ticks, texture on " << tactile_textured << " finger-ticks, the skin slipped on "
       << tactile_slips << ", " << tactile_clamped << " samples clamped by the gate";
  os << "\n";
  if (refinement_updates > 0)
    os << "local refinement " << refinement_builds << " children built, " << refinement_updates << " updates "
       << (refinement_beside_steps ? "beside the steps (worker thread)" : "within the steps") << "\n";
  if (energy_bound_ticks > 0)
    os << "energy bound     the multirate model's force scaled back on " << energy_bound_ticks
       << " ticks, " << std::setprecision(2) << energy_withheld * 1e6
       << " uJ withheld (more than the hand had put in)\n" << std::setprecision(1);
  os << "scheduling       " << scheduling_note << (memory_locked ? ", memory locked" : "") << "\n";
  return os.str();
}

std::string SessionReport::to_json() const {
  nlohmann::json j;
  auto h = [](const Histogram& x) {
    return nlohmann::json{{"p50", x.quantile(0.5)}, {"p99", x.quantile(0.99)},
                          {"p999", x.quantile(0.999)}, {"max", x.max()}};
  };
  j["haptic_ticks"] = haptic.ticks;
  j["missed_deadlines"] = haptic.missed_deadlines;
  j["overruns"] = haptic.overruns;
  j["period_error_us"] = h(haptic.period_error_us);
  j["compute_us"] = h(haptic.compute_us);
  j["sim_step_us"] = h(sim_step_us);
  j["sim_helper_wait_us"] = h(sim_helper_wait_us);
  j["sim_helper_wait_us"]["steps_over_100us"] = sim_helper_wait_us.fraction_at_least(100.0);
  j["sim_steps"] = sim_steps;
  j["sim_time_s"] = sim_time;
  j["cloth_time_s"] = cloth_time;
  j["cloth_time_ratio"] = cloth_time_ratio();
  j["contact_ticks"] = contact_ticks;
  j["slip_ticks"] = slip_ticks;
  j["max_force_n"] = max_force;
  j["out_of_reach_ticks"] = out_of_reach_ticks;
  j["patch_rebuilds"] = patch_rebuilds;
  j["patch_softened"] = patch_softened;
  j["patch_candidate_overflows"] = patch_candidate_overflows;
  j["device_errors"] = device_errors;
  j["contact_samples"] = contact_samples;
  j["contact_revisions"] = contact_revisions;
  j["contact_line_cuts"] = contact_line_cuts;
  j["contact_settles"] = contact_settles;
  j["contact_confirmations"] = contact_confirmations;
  j["max_penetration_m"] = max_penetration;
  j["late_ticks"] = late_ticks;
  j["tactile"] = {{"mode", tactile}, {"frames", tactile_frames}, {"textured", tactile_textured},
                  {"slips", tactile_slips}, {"clamped", tactile_clamped}};
  j["passivity_ticks"] = passivity_ticks;
  j["passivity_deficit_j"] = passivity_deficit;
  j["energy_bound_ticks"] = energy_bound_ticks;
  j["energy_withheld_j"] = energy_withheld;
  j["refinement_builds"] = refinement_builds;
  j["refinement_updates"] = refinement_updates;
  j["refinement_beside_steps"] = refinement_beside_steps;
  j["realtime_scheduling"] = realtime_scheduling;
  j["memory_locked"] = memory_locked;
  return j.dump();
}

}  // namespace hapticloth::haptics
