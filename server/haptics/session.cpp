// The session's wiring (session.hpp): the simulation worker, the haptic loop, the device and
// the tactile channel put together, and its start and stop. The real-time threads are in
// session_threads.cpp, the report in session_report.cpp.
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

void Session::observe_step() {
  if (const RefinementSchedule* r = sim_->refinement(); r && r->regions().version != regions_seen_) {
    regions_seen_ = r->regions().version;
    for (auto* o : observers_) o->on_refined(r->regions());
  }
  for (auto* o : observers_) o->on_sim_step(sim_->last_snapshot());
}

}  // namespace hapticloth::haptics
