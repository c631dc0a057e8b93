// A haptic session: the global simulation and the 1 kHz haptic loop around one device.
// Real time: two threads (the haptic thread on absolute clock_nanosleep deadlines, or on the
// device's samples with device_clock, SCHED_FIFO and mlockall when permitted; the simulation
// thread at its own rate) exchanging state through lock-free triple buffers. Stepped: both in
// one thread on a simulated clock, deterministic, as fast as possible (tests, replays).
#pragma once

#include <atomic>
#include <chrono>
#include <cmath>
#include <memory>
#include <string>

#include "cloth/integrator.hpp"
#include "hal/handle.hpp"
#include "hal/safety_gate.hpp"
#include "haptics/loop/haptic_loop.hpp"
#include "haptics/observer.hpp"
#include "haptics/sim/sim_worker.hpp"

namespace hapticloth::haptics {

struct SessionConfig {
  double haptic_rate = 1000.0;  ///< Hz
  FingerParams finger;
  CouplingParams coupling;
  DeviceMapping mapping;
  devices::GateConfig gate;
  bool try_realtime = true;     ///< SCHED_FIFO + mlockall for the haptic thread if permitted
  /// How the simulation and the haptic loop share the fingertips (rendering.hpp). The server
  /// takes the multirate path when the global step does not fit in the haptic period (the
  /// scene's haptics.rendering).
  Rendering rendering = Rendering::Direct;
  PatchParams patch;            ///< the patch model's; stiffness and density are taken from the material
  double spin_lead = 150e-6;    ///< s: the haptic thread sleeps to this before each deadline, then spins
  /// Real time: tick on the device's samples (devices::DeviceClock) instead of the loop's own
  /// deadlines. The device must stream on its own clock (paces_loop: udp).
  bool device_clock = false;
};

struct SessionReport {
  LoopStats haptic;
  Histogram sim_step_us;
  /// Of each sim step, the wait for the integrator's helper thread (two threads; 0 on one): the
  /// steps with long waits are those of a slowed helper core, not of the step's own work.
  Histogram sim_helper_wait_us;
  std::uint64_t sim_steps = 0, contact_ticks = 0, slip_ticks = 0, out_of_reach_ticks = 0;
  std::uint64_t device_errors = 0;
  /// Direct coupling: cloth samples in contact summed over steps, steps re-solved because the
  /// contact set changed, and the deepest any cloth point got inside a fingertip sphere (m).
  std::uint64_t contact_samples = 0, contact_revisions = 0;
  std::uint64_t contact_line_cuts = 0;  ///< re-solves the active set's line search took only part of
  /// Re-solves that settled the contacts' rows alone, and the whole solves that confirmed them.
  std::uint64_t contact_settles = 0, contact_confirmations = 0;
  double max_penetration = 0.0;
  std::uint64_t patch_rebuilds = 0, patch_softened = 0;  ///< local patch builds (4.2)
  /// Snapshots that listed fewer patch candidates than a finger had (SimWorker).
  std::uint64_t patch_candidate_overflows = 0;
  /// Ticks more than half a period late, and the coupling's passivity controller (passivity.hpp):
  /// ticks it added damping on, and the most energy the coupling gave beyond passivity (J).
  std::uint64_t late_ticks = 0, passivity_ticks = 0;
  double passivity_deficit = 0.0;
  /// The multirate path's energy bound (energy_bound.hpp): ticks on which it scaled a force back,
  /// and the work on the hand it withheld, J.
  std::uint64_t energy_bound_ticks = 0;
  double energy_withheld = 0.0;
  /// Local refinement (LocalRefinement): children built, and updates (settles of every touching
  /// child) done, within the steps or beside them (refinement_schedule.hpp).
  std::uint64_t refinement_builds = 0, refinement_updates = 0;
  bool refinement_beside_steps = false;
  /// The tactile half (tactile_rendering.hpp): what it renders ("off" and why, when nothing),
  /// ticks rendered, finger-ticks with texture and with a slip of the skin, and the gate's
  /// tactile clamps.
  std::string tactile = "off: the device declares no tactile display";
  std::uint64_t tactile_frames = 0, tactile_textured = 0, tactile_slips = 0, tactile_clamped = 0;
  double max_force = 0.0;          ///< N, largest force sent to a finger
  double sim_time = 0.0;           ///< s of session: the haptic ticks run times the haptic period
  /// s the cloth advanced in the session (its steps times their dt). Below sim_time when the
  /// global step takes longer than its dt in real time: the cloth then moves in slow motion
  /// against the hand (cloth_time / sim_time of real time).
  double cloth_time = 0.0;
  bool realtime_scheduling = false;
  bool memory_locked = false;
  std::string scheduling_note;     ///< why real-time scheduling is on or off
  std::uint64_t missed_deadlines() const { return haptic.missed_deadlines; }
  /// cloth_time / sim_time (0 before any tick): 1 when the cloth keeps pace with the hand.
  double cloth_time_ratio() const { return sim_time > 0.0 ? cloth_time / sim_time : 0.0; }
  std::string to_text() const;
  std::string to_json() const;
};

class Session {
 public:
  /// The device must be configured; the session activates and deactivates it.
  Session(const cloth::ClothModel& model, const cloth::IntegratorConfig& cfg,
          std::unique_ptr<cloth::LinearSolver> solver, const cloth::ClothState& start,
          devices::DeviceHandle& device, const SessionConfig& sc);
  ~Session();

  /// Both loops in one thread on a simulated clock for `seconds`; the simulation steps every
  /// `sim_period` (s, a multiple of the haptic period; 0 = the integrator's dt).
  /// `on_tick` (optional) is called after every haptic tick.
  template <class F>
  void run_stepped(double seconds, double sim_period, F&& on_tick) {
    run_stepped_late(seconds, sim_period, [](long) { return 0.0; }, on_tick);
  }
  void run_stepped(double seconds, double sim_period = 0.0) {
    run_stepped(seconds, sim_period, [](const HapticLoop&, const SimWorker&) {});
  }
  /// The stepped clock with late ticks: tick k starts `late(k)` seconds after its time, and
  /// every later tick with it (a kernel that wakes the haptic thread late delays the loop's
  /// schedule). `seconds` counts the ticks (seconds x the haptic rate of them); the simulation
  /// steps on tick counts, as the stepped clock always does.
  template <class L, class F>
  void run_stepped_late(double seconds, double sim_period, L&& late, F&& on_tick);
  /// Real time for `seconds`: haptic thread at the haptic rate, simulation thread as fast as
  /// its step allows, up to one step per integrator dt.
  void run_realtime(double seconds);

  /// A run ends at its next haptic tick once `*flag` is true (a stop signal); the report then
  /// covers the time run.
  void set_stop_flag(const std::atomic<bool>* flag) { stop_request_ = flag; }

  /// Observers are called on the loops' threads (see SessionObserver); add before running.
  void add_observer(SessionObserver* o) { observers_.push_back(o); }

  SessionReport report() const;
  HapticLoop& haptics() { return *loop_; }
  SimWorker& sim() { return *sim_; }
  devices::SafetyGate& gate() { return *gate_; }

 private:
  void start();
  void stop();
  void account_tick();
  void attach_tactile(const cloth::ClothModel& model);
  /// The observers see the step just taken: the refined children if they changed, then the
  /// cloth (simulation thread).
  void observe_step();
  // run_realtime()'s threads.
  void sim_thread_loop(double t_start, const std::atomic<bool>& stop_flag);
  std::string haptic_thread_priority();
  long haptic_ticks(double seconds, double t_start, double period);
  long device_paced_ticks(double seconds, double t_start, double period);
  double haptic_tick(long k, double woke, double t_start);
  void realtime_wind_down(long next, double t_start, double period);
  double wake_at(double deadline) const;
  void notify_tick() noexcept;
  /// Most closing ticks that bring the force to zero through the gate's slew limit (the
  /// default 1000 N/s takes 5 ms from 5 N).
  static constexpr long kWindDownTicks = 200;
  bool stop_requested() const { return stop_request_ && stop_request_->load(std::memory_order_relaxed); }

  devices::DeviceHandle& dev_;
  SessionConfig sc_;
  double dt_sim_;
  double cloth_start_;  // the cloth's time at the session's start, s
  std::unique_ptr<devices::SafetyGate> gate_;
  std::unique_ptr<TripleBuffer<ClothSnapshot>> snap_;
  std::unique_ptr<TripleBuffer<HapticReport>> rep_;
  std::unique_ptr<SimWorker> sim_;
  std::unique_ptr<HapticLoop> loop_;
  std::vector<SessionObserver*> observers_;
  std::uint64_t regions_seen_ = 0;  // RefinedRegions::version the observers last saw
  const std::atomic<bool>* stop_request_ = nullptr;
  SessionReport r_;
  std::string tactile_note_ = "off: the device declares no tactile display";
};

template <class L, class F>
void Session::run_stepped_late(double seconds, double sim_period, L&& late, F&& on_tick) {
  start();
  loop_->prime(0.0);
  r_.scheduling_note = "stepped clock (no real-time scheduling)";
  const double hp = 1.0 / sc_.haptic_rate;
  const double sp = sim_period > 0.0 ? sim_period : dt_sim_;
  const long every = std::max(1L, std::lround(sp / hp));
  const long ticks = std::lround(seconds / hp);
  long k = 0;
  double shift = 0.0;
  for (; k < ticks && !stop_requested(); ++k) {
    shift += late(k);
    const double now = k * hp + shift;
    if (k % every == 0) {
      sim_->step(now);
      observe_step();
    }
    const auto t0 = std::chrono::steady_clock::now();
    loop_->tick(now);
    r_.haptic.compute_us.add(
        std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
    ++r_.haptic.ticks;
    account_tick();
    notify_tick();
    on_tick(*loop_, *sim_);
  }
  r_.sim_time = k * hp;
  for (long j = 0; j < kWindDownTicks; ++j) {
    const bool done = loop_->wind_down((k + j) * hp + shift);
    notify_tick();
    if (done) break;
  }
  stop();
}

}  // namespace hapticloth::haptics
