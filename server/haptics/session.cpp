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
#include "haptics/deadlines.hpp"
#include "haptics/refinement_schedule.hpp"
#include "haptics/rendering_modes.hpp"

namespace hapticloth::haptics {

using devices::mono_now;
using devices::to_timespec;

namespace {
ClothSnapshot sized_snapshot(int vertices, int patch_candidates) {
  ClothSnapshot s;
  s.resize(vertices, patch_candidates);
  return s;
}
}  // namespace

Session::Session(const cloth::ClothModel& model, const cloth::IntegratorConfig& cfg,
                 std::unique_ptr<cloth::LinearSolver> solver, const cloth::ClothState& start,
                 devices::DeviceHandle& device, const SessionConfig& sc)
    : dev_(device), sc_(sc), dt_sim_(cfg.dt), cloth_start_(start.time) {
  if (dev_.state() != devices::Lifecycle::Inactive)
    throw std::invalid_argument("session: the device must be configured (inactive)");
  if (!(sc_.haptic_rate > 0.0)) throw std::invalid_argument("session: haptic_rate must be > 0");
  // The device renders no stiffer a spring stably: the coupling is clamped to its limit for
  // both surface models (the proxy's spring in the implicit step and the patch's contact).
  sc_.finger.stiffness = std::min(sc_.finger.stiffness, dev_.info().max_stiffness);
  if (sc_.device_clock && !dev_.device().paces_loop())
    throw std::invalid_argument("session: device.clock \"device\" needs a device that streams on "
                                "its own clock (udp), not " + dev_.info().name);
  gate_ = std::make_unique<devices::SafetyGate>(dev_.info(), sc_.gate);
  // Nor does it render more than the gate's limit: the cloth gets no more either (third law).
  sc_.finger.max_force = gate_->max_force();
  const Rendering mode = sc_.rendering;
  const int fingers = dev_.info().fingers;
  const PatchParams patch = patch_params(sc_.patch, model, sc_.finger, sc_.coupling, sc_.haptic_rate);
  // The patch model's candidates: room for 4x the triangles a patch takes.
  const int candidates = mode == Rendering::Patch ? 4 * std::max(1, sc_.patch.max_triangles) : 0;
  snap_ = std::make_unique<TripleBuffer<ClothSnapshot>>(sized_snapshot(model.num_vertices(), candidates));
  rep_ = std::make_unique<TripleBuffer<HapticReport>>(HapticReport{});
  sim_ = std::make_unique<SimWorker>(model, cfg, std::move(solver), start, fingers, sc_.finger, sc_.coupling,
                                     mode, patch, *snap_, *rep_);
  loop_ = std::make_unique<HapticLoop>(dev_, *gate_, sc_.finger, sc_.mapping,
                                       make_surface_contact(mode, model, fingers, sc_.finger, patch), mode,
                                       *snap_, *rep_);
  attach_tactile(model);
}

// The tactile half, for a device with a tactile display on a fabric with a surface.
void Session::attach_tactile(const cloth::ClothModel& model) {
  const devices::TactileCapability& cap = dev_.info().tactile;
  if (!cap.any()) return;
  if (!model.material.surface.present()) {
    tactile_note_ = "off: the device has a tactile display, but the material has no [surface]";
    return;
  }
  std::ostringstream os;
  os << "on: ";
  if (cap.vibration()) os << "vibration at " << cap.vibration_rate << " Hz";
  if (cap.pins()) os << (cap.vibration() ? ", " : "") << cap.pin_rows << " x " << cap.pin_cols << " pins at "
                     << cap.pin_pitch * 1e3 << " mm";
  os << " per finger, from the material's [surface]";
  tactile_note_ = os.str();
  loop_->attach_tactile(std::make_unique<TactileRendering>(model, cap, dev_.info().fingers,
                                                           1.0 / sc_.haptic_rate, sc_.finger.radius));
}

Session::~Session() { dev_.deactivate(); }

void Session::start() {
  if (dev_.state() == devices::Lifecycle::Inactive) {
    const std::string e = dev_.activate();
    if (!e.empty()) throw std::runtime_error("device: " + e);
  }
  gate_->reset();
}

void Session::stop() { dev_.deactivate(); }

void Session::account_tick() {
  const HapticReport& r = loop_->last_report();
  for (int f = 0; f < loop_->fingers(); ++f) {
    r_.max_force = std::max(r_.max_force, loop_->last_command().force[f].norm());
    if (r.finger[f].slipping) ++r_.slip_ticks;
  }
}

void Session::run_realtime(double seconds) {
  start();
  std::atomic<bool> stop_flag{false};
  long elapsed_ticks = 0;  // written by the haptic thread, read after it joined
  r_.haptic = LoopStats{};
  // Real-time scheduling when permitted; a clean fallback (with the reason) when not.
  r_.memory_locked = sc_.try_realtime && mlockall(MCL_CURRENT | MCL_FUTURE) == 0;
  std::unique_ptr<devices::CpuLatencyHold> idle;  // shallow idle states: the deadline's wake-up 25 us sooner
  if (sc_.try_realtime) idle = std::make_unique<devices::CpuLatencyHold>();
  std::string note;
  const double period = 1.0 / sc_.haptic_rate;
  const double t_start = mono_now() + 0.01;
  // In real time the refinement's settles run beside the steps (refinement_schedule.hpp).
  sim_->refine_beside_steps();
  // The haptic loop reports the fingertips, then the simulation publishes once, before the
  // loops start.
  loop_->prime(0.0);
  sim_->publish(0.0);
  std::thread sim_thread([&] { sim_thread_loop(t_start, stop_flag); });
  std::thread haptic_thread([&] {
    note = haptic_thread_priority();
    elapsed_ticks = haptic_ticks(seconds, t_start, period);
    realtime_wind_down(elapsed_ticks, t_start, period);
  });
  haptic_thread.join();
  stop_flag = true;
  sim_thread.join();
  r_.sim_time = static_cast<double>(elapsed_ticks) * period;
  r_.scheduling_note = idle ? note + ", " + idle->note() : note;
  if (r_.memory_locked) munlockall();
  stop();
}

void Session::observe_step() {
  if (const RefinementSchedule* r = sim_->refinement(); r && r->regions().version != regions_seen_) {
    regions_seen_ = r->regions().version;
    for (auto* o : observers_) o->on_refined(r->regions());
  }
  for (auto* o : observers_) o->on_sim_step(sim_->last_snapshot());
}

// The simulation thread: a step per integrator dt on absolute deadlines, as fast as the step
// allows when behind.
void Session::sim_thread_loop(double t_start, const std::atomic<bool>& stop_flag) {
  double next = t_start;
  while (!stop_flag.load(std::memory_order_relaxed)) {
    const double now = mono_now() - t_start;
    sim_->step(now);
    observe_step();
    next += dt_sim_;
    const double t = mono_now();
    if (next > t) {
      const timespec ts = to_timespec(next);
      clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
    } else {
      next = t;  // behind: run as fast as the step allows
    }
  }
}

// SCHED_FIFO for the calling (haptic) thread when asked and permitted; returns what it got.
std::string Session::haptic_thread_priority() {
  prctl(PR_SET_TIMERSLACK, 1UL, 0, 0, 0);  // wake on the deadline, not up to 50 us later
  if (!sc_.try_realtime) return "real-time scheduling not requested";
  sched_param sp{};
  sp.sched_priority = devices::kHapticThreadPriority;
  const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
  r_.realtime_scheduling = rc == 0;
  return rc == 0 ? "SCHED_FIFO priority " + std::to_string(devices::kHapticThreadPriority)
                 : std::string("SCHED_FIFO refused (") + std::strerror(rc) + "): normal scheduling";
}

// The haptic loop at its rate for `seconds` (or until a stop request): returns the ticks due.
long Session::haptic_ticks(double seconds, double t_start, double period) {
  if (sc_.device_clock) return device_paced_ticks(seconds, t_start, period);
  const long ticks = std::lround(seconds * sc_.haptic_rate);
  long elapsed = 0;
  for (long k = 0; k < ticks && !stop_requested(); ++k) {
    const double deadline = t_start + k * period;
    const double woke = wake_at(deadline);
    r_.haptic.period_error_us.add(std::abs(woke - deadline) * 1e6);
    k = tick_after_wake(k, ticks, woke, t_start, period, r_.haptic);
    elapsed = k + 1;
    const double done = haptic_tick(k, woke, t_start);
    count_deadline(woke, done, t_start + (k + 1) * period, period, r_.haptic);
  }
  return elapsed;
}

// The haptic loop on the device's samples for `seconds` (or until a stop request): a tick as
// each sample arrives (DeviceClock). The period error is how far a tick's interval from the
// last is from the period, between two ticks on samples (the device's own jitter and this
// thread's wake-up together); a tick whose compute overruns the period is a missed deadline.
// Ticks without a sample (the device silent for 1.5 periods) show as samples < ticks in the
// device counters. Returns the ticks due in the time run.
long Session::device_paced_ticks(double seconds, double t_start, double period) {
  const devices::DeviceClock clock(period);
  const double end = t_start + seconds;
  double last = t_start - devices::DeviceClock::kEarliest * period;  // the first tick at t_start at the soonest
  bool last_sampled = false;
  for (long k = 0; !stop_requested(); ++k) {
    const devices::DeviceClock::Tick t = clock.wait(dev_, last);
    if (t.at >= end) break;
    if (t.sampled && last_sampled) r_.haptic.period_error_us.add(std::abs(t.at - last - period) * 1e6);
    last = t.at;
    last_sampled = t.sampled;
    const double done = haptic_tick(k, t.at, t_start);
    count_deadline(t.at, done, t.at + period, period, r_.haptic);
  }
  return std::lround((std::min(mono_now(), end) - t_start) / period);
}

// One tick of the haptic loop at `woke` (CLOCK_MONOTONIC, s), its observers and its compute
// time; returns when it was done.
double Session::haptic_tick(long k, double woke, double t_start) {
  loop_->tick(woke - t_start);
  account_tick();
  notify_tick();
  if (k % 1000 == 999)
    for (auto* o : observers_) o->on_loop_stats(r_.haptic);
  const double done = mono_now();
  r_.haptic.compute_us.add((done - woke) * 1e6);
  ++r_.haptic.ticks;
  return done;
}

// Sleeps to just before `deadline`, then spins the rest: the kernel's wake-up is late by tens
// of microseconds (more on a virtual machine); the spin costs spin_lead of CPU per tick.
// Returns the wake-up.
double Session::wake_at(double deadline) const {
  const timespec ts = to_timespec(deadline - sc_.spin_lead);
  clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
  double woke = mono_now();
  while (woke < deadline) woke = mono_now();
  return woke;
}

// The end (of the run, or a stop signal): zero force through the gate, at the loop rate, on
// the loop's deadline grid from deadline `next` on (or the first one still ahead), so that the
// ticks' times in the log stay where the loop's deadlines are.
void Session::realtime_wind_down(long next, double t_start, double period) {
  long k = std::max(next, static_cast<long>((mono_now() - t_start) / period) + 1);
  for (long j = 0; j < kWindDownTicks; ++j, ++k) {
    const bool done = loop_->wind_down(wake_at(t_start + k * period) - t_start);
    notify_tick();
    if (done) break;
  }
}

// The observers see the haptic loop's last tick.
void Session::notify_tick() noexcept {
  for (auto* o : observers_)
    o->on_haptic_tick(loop_->last_report(), loop_->device_state(), loop_->last_command());
  if (loop_->tactile())
    for (auto* o : observers_) o->on_tactile(loop_->last_report(), *loop_->tactile(), loop_->last_tactile());
}

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
