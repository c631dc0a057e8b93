#include "app/serve.hpp"

#include "app/stop_signal.hpp"
#include "app/toml_file.hpp"

#include <algorithm>
#include <csignal>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <iostream>
#include <optional>
#include <sstream>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "hal/handle.hpp"
#include "hal/safety_gate.hpp"
#include "hal/platform_timer.hpp"
#include "haptics/refinement/local_refinement.hpp"
#include "haptics/session.hpp"
#include "haptics/loop/tactile_trace.hpp"
#include "registry.hpp"
#include "remote/command_sink.hpp"
#include "transport/foxglove_sink.hpp"
#include "transport/hub.hpp"
#include "transport/zenoh_session.hpp"

namespace hapticloth::app {

namespace {

// Local refinement (direct coupling and the response model): whether the mesh resolves the fingertip's contact patch,
// and what is done where it does not.
std::string refinement_stage(const Scene& sc, const cloth::ClothModel& m) {
  const haptics::RefinementParams& r = sc.haptics.coupling.refinement;
  const double radius = sc.haptics.finger.radius, finest = haptics::finest_edge(r, radius);
  std::ostringstream os;
  os << std::fixed << std::setprecision(1) << "edges up to " << haptics::longest_rest_edge(m) * 1e3
     << " mm against a " << radius * 1e3 << " mm fingertip, whose contact patch " << finest * 1e3
     << " mm edges resolve: ";
  const haptics::Refine asked = sc.haptics.coupling.refine;
  const haptics::Rendering mode = sc.haptics.rendering;
  if (mode == haptics::Rendering::Patch)
    os << (asked == haptics::Refine::Off ? "local refinement off (the patch model has its own patch)"
                                         : "no local refinement: the patch model renders from its own "
                                           "subdivided patch");
  else if (!haptics::mesh_needs_refinement(m, r, radius))
    os << "no local refinement needed";
  else if (haptics::refines(asked))
    os << "local refinement on (haptics.refine = \"" << haptics::to_string(asked) << "\"), a child mesh graded from "
       << finest * 1e3 << " mm under each touching fingertip where its triangle is coarser (docs/contact.md)";
  else
    os << "local refinement off (haptics.refine = \"off\"), so the felt force is stiffer than the "
          "cloth's (docs/contact.md gives by how much)";
  return os.str();
}

// What the scene needs, and why: one short line per stage.
std::vector<std::string> stages(const Scene& sc, const cloth::ClothModel& m, double step_ms,
                                double haptic_period_ms) {
  std::vector<std::string> s;
  std::ostringstream os;
  os << std::fixed << std::setprecision(3);
  const bool fits = step_ms <= haptic_period_ms;
  const haptics::Rendering mode = sc.haptics.rendering;
  const char* why = sc.rendering == "multirate" ? "asked for" : "the global step";
  if (mode == haptics::Rendering::Response) {
    os << "multirate, local model response (" << why
       << " " << step_ms << " ms median at start-up, its matrix formed whole, vs the " << haptic_period_ms
       << " ms haptic period): fingertips solved with the cloth every " << sc.integrator.dt * 1e3
       << " ms, rendered between steps from the cloth's linear response (docs/contact.md)";
  } else if (mode == haptics::Rendering::Patch) {
    os << "multirate, local model patch (" << why
       << " " << step_ms << " ms median at start-up, its matrix formed whole, vs the " << haptic_period_ms
       << " ms haptic period): a subdivided patch per fingertip at the haptic rate; it does not"
       << " hold a pinch (BENCHMARKS.md)";
  } else if (fits) {
    os << "direct coupling (" << (sc.rendering == "direct" ? "asked for" : "the global step fits")
       << "): the global step takes " << step_ms
       << " ms (median at start-up, its matrix formed whole), within the " << haptic_period_ms
       << " ms haptic period: the fingertips are spheres solved with the whole cloth";
  } else {
    os << "direct coupling (asked for): the global step " << step_ms << " ms > haptic period "
       << haptic_period_ms << " ms; the fingertips are solved with the cloth and the force of the"
       << " last step is rendered until the next";
  }
  s.push_back(os.str());
  s.push_back(refinement_stage(sc, m));
  if (sc.integrator.alpha < 1.0) {
    std::ostringstream a;
    a << "alpha " << sc.integrator.alpha;
    if (mode == haptics::Rendering::Patch)
      a << " < 1 with the patch model: alpha 1 from the first energy explosion on (BENCHMARKS.md)";
    else  // the proxies are solved with the cloth (direct coupling, response model)
      a << " < 1 asked for, alpha 1 used for the fingertips' stiff contacts (docs/contact.md)";
    s.push_back(a.str());
  }
  const cloth::SimdLevel level = sc.integrator.element_level();
  s.push_back(std::string("element pass on ") + cloth::to_string(level) + ", lanes of " +
              std::to_string(cloth::element_kernels(level).lanes) + " doubles (" +
              (sc.integrator.simd ? "asked for" : "the widest level this CPU runs") + ")");
  s.push_back(sc.material.viscous() ? "strain-rate (viscous) terms on: the material has viscosity"
                                    : "strain-rate terms off: the material has no viscosity");
  s.push_back(m.pins_count() > 0 ? "pinned vertices: " + std::to_string(m.pins_count()) + " move kinematically"
                                 : "no pins: no constraint work");
  s.push_back("narrow phase only on ticks where a fingertip is within the broad-phase margin of the cloth");
  return s;
}

// The device's dropped-packet total, handed to the Hub (which publishes an event when it grows)
// from the haptic thread, the thread that also writes the counters.
struct DropReporter : haptics::SessionObserver {
  const devices::Device* dev = nullptr;
  transport::Hub* hub = nullptr;
  void on_loop_stats(const haptics::LoopStats&) noexcept override {
    if (hub && dev) hub->note_dropped_packets(dev->counters().dropped_total());
  }
};

// What serve() runs: the settled cloth, the session's settings and the stage lines; for a
// real-time session, the platform's timer measured while the cloth settled.
struct Plan {
  cloth::ClothState state;
  haptics::SessionConfig session;
  std::vector<std::string> stages;
  std::optional<devices::TimerFigures> platform;
};

// The platform timer beside a real-time session: taken while the preroll runs on the other core
// (the load the haptic thread then runs beside: the cloth's steps), at the haptic thread's
// scheduling, for at least this many ticks. Not during the session: a second SCHED_FIFO thread
// waking every millisecond would disturb the loop it is the reference for.
constexpr long kPlatformTicksMin = 1000;
constexpr long kPlatformTicksMax = 600000;  // 10 min at 1 kHz: a preroll longer than that stops it

// Steps the cloth for the scene's preroll as fast as possible; returns each step's time, ms.
// The preroll forms the matrix whole every step (matrix_refresh 0): the coupling is chosen from
// what a step costs when the cloth moves everywhere, not from the cloth at rest that the preroll
// ends in, whose kept matrix costs less (docs/performance.md, "The kept matrix").
std::vector<double> settle(const Scene& scene, const cloth::ClothModel& model, cloth::ClothState& state,
                           const std::atomic<bool>* stop) {
  std::vector<double> step_ms;
  Scene formed_whole = scene;
  formed_whole.integrator.matrix_refresh = 0.0;
  auto integ = make_integrator(formed_whole, model);
  const long n = std::max(20L, std::lround(scene.preroll / scene.integrator.dt));
  for (long k = 0; k < n && !(stop && stop->load()); ++k) {
    integ->step(state);
    step_ms.push_back(integ->last_timing().total_ms);
  }
  state.time = 0.0;
  return step_ms;
}

// Settles the scene for its preroll as fast as possible, measuring the global step (and, for a
// real-time session, the platform's timer meanwhile); chooses the coupling from the step
// (scene.integrator.dt may be shortened to the haptic period) and says why.
Plan plan(Scene& scene, const cloth::ClothModel& model, const devices::DeviceHandle& dev,
          bool realtime, const std::atomic<bool>* stop) {
  Plan p{cloth::rest_state(model), scene.haptics, {}, std::nullopt};
  std::vector<double> step_ms;
  if (realtime) {
    std::atomic<bool> settled{false};
    devices::TimerFigures timer;
    std::thread t([&] {
      timer = devices::measure_timer(kPlatformTicksMax, 1.0 / scene.haptics.haptic_rate,
                                     devices::kHapticThreadPriority, &settled,
                                     kPlatformTicksMin, stop);
    });
    step_ms = settle(scene, model, p.state, stop);
    settled = true;
    t.join();
    p.platform = timer;
  } else {
    step_ms = settle(scene, model, p.state, stop);
  }
  std::sort(step_ms.begin(), step_ms.end());
  const double median_ms = step_ms[step_ms.size() / 2];
  haptics::SessionConfig& sc = p.session;
  const bool multirate =
      scene.rendering == "multirate" || (scene.rendering == "auto" && median_ms > 1000.0 / sc.haptic_rate);
  scene.haptics.rendering = sc.rendering = haptics::rendering(multirate, scene.multirate_model);
  // Direct coupling renders the force of the last global step (the fingertips are solved with
  // the cloth): with a longer step it stays stable but the force changes only once per step,
  // a staircase the hand feels. So the step is shortened to the haptic period.
  std::string dt_note;
  const double period = 1.0 / sc.haptic_rate;
  if (!multirate && scene.integrator.dt > period * (1.0 + 1e-9)) {
    std::ostringstream os;
    os << "global dt " << scene.integrator.dt * 1e3 << " ms shortened to the haptic period "
       << period * 1e3 << " ms (direct coupling renders each global step's force)";
    dt_note = os.str();
    scene.integrator.dt = period;
  }
  p.stages = stages(scene, model, median_ms, 1000.0 / sc.haptic_rate);
  if (!dt_note.empty()) p.stages.insert(p.stages.begin() + 1, dt_note);
  if (sc.finger.stiffness > dev.info().max_stiffness) {
    std::ostringstream os;
    os << "coupling stiffness " << sc.finger.stiffness << " N/m clamped to the device's max_stiffness "
       << dev.info().max_stiffness << " N/m ([haptics] stiffness)";
    p.stages.insert(p.stages.begin() + 1, os.str());
  }
  return p;
}

// ws://HOST:PORT of the live view, with the port it got (the one asked for, or any free one for 0).
std::string foxglove_address(const std::string& asked, std::uint16_t port) {
  return "ws://" + asked.substr(0, asked.rfind(':')) + ":" + std::to_string(port);
}

// The Foxglove channels' message counts: "/cloth 120, /fingertips 200, ...".
std::string foxglove_counts(const transport::FoxgloveSink& fox) {
  std::string s;
  for (int c = 0; c < transport::FoxgloveSink::kChannels; ++c) {
    const auto ch = static_cast<transport::FoxgloveSink::Channel>(c);
    s += (c ? ", " : "") + std::string(transport::FoxgloveSink::channel_name(ch)) + " " + std::to_string(fox.written(ch));
  }
  return s;
}

// The Hub that publishes the session over zenoh / LCM and feeds a remote device, opened before
// the preroll: a bad endpoint, config file or Foxglove host, or a port in use, is exit 2 before
// anything runs. Without zenoh (and says so) when only its endpoint cannot be opened and zenoh
// is not required.
std::unique_ptr<transport::Hub> open_transport(const Scene& scene, const ServeOptions& opt,
                                               devices::DeviceHandle& dev, std::ostream& out) {
  const haptics::SessionConfig& sc = scene.haptics;  // what the Hub reads the plan leaves as is
  transport::SceneInfo info;
  transport::set_cloth(info, scene.mesh, scene.material);
  info.scene_name = scene.name;
  info.device = dev.info();
  info.device_rotation = sc.mapping.R;
  info.device_origin = sc.mapping.origin;
  info.haptic_rate = sc.haptic_rate;
  transport::TransportOptions to = opt.transport;
  to.finger_radius = sc.finger.radius;
  to.hold_until_session = true;  // clients get the scene, and commands are taken, once it runs
  std::unique_ptr<transport::Hub> hub;
  try {
    hub = transport::make_hub(to, info);
  } catch (const transport::ZenohOpenError& e) {
    if (opt.transport_required || !to.zenoh) throw;
    std::cerr << "hapticloth-server: " << e.what() << "; running without zenoh\n";
    to.zenoh = false;
    hub = transport::make_hub(to, info);
  }
  if (auto* sink = dynamic_cast<devices::RemoteCommandSink*>(&dev.device())) hub->set_command_sink(sink);
  if (!opt.json) {
    const auto& o = hub->options();
    out << "transport        zenoh " << (o.zenoh && to.zenoh ? "hapticloth/" + o.server_name + "/* on " +
                                                 (o.zenoh_config.empty() ? o.zenoh_listen : o.zenoh_config)
                                              : std::string("off"))
        << ", LCM " << (o.lcm_url.empty() ? "off" : o.lcm_url) << ", log "
        << (o.lcm_log.empty() ? "off" : o.lcm_log) << "\n";
    if (const transport::FoxgloveSink* fox = hub->foxglove())
      out << "foxglove         live " << (o.foxglove.empty() ? std::string("off") : foxglove_address(o.foxglove, fox->port()))
          << ", MCAP " << (o.mcap.empty() ? "off" : o.mcap) << "\n";
  }
  return hub;
}

// The Hub (and the dropped-packet reporter) observe the session; the `started` event, which
// names the clock the ticks' times are on (hapticloth-plot measures the period error by it).
void attach(const Scene& scene, const ServeOptions& opt, devices::DeviceHandle& dev,
            haptics::Session& session, transport::Hub& hub, DropReporter& drops) {
  drops.dev = &dev.device();
  drops.hub = &hub;
  session.add_observer(&hub);
  session.add_observer(&drops);
  hub.session_started();
  const char* clock = !opt.realtime ? "stepped" : scene.haptics.device_clock ? "device" : "loop";
  hub.post_event("started", "scene " + scene.name + ", device " + dev.info().name + ", clock " + clock);
}

// With a tactile display: a trace of what each fingertip's skin got, for the summary's line on
// whether the vibration followed the stroke (tactile_trace.hpp): of the first kTactileTraceSeconds
// (a longer run's later ticks are counted, not kept: 15 MB for two fingers at 4 kHz).
constexpr double kTactileTraceSeconds = 120.0;

std::unique_ptr<haptics::TactileTrace> tactile_trace(const cloth::ClothModel& model, haptics::Session& session,
                                                     double duration) {
  const haptics::TactileRendering* t = session.haptics().tactile();
  if (!t) return nullptr;
  const double rate = 1.0 / session.haptics().period();  // ticks a second
  const devices::TactileCapability& cap = t->capability();
  const int block = cap.vibration() ? static_cast<int>(std::lround(cap.vibration_rate / rate)) : 1;
  auto trace = std::make_unique<haptics::TactileTrace>(model.material.surface, session.haptics().fingers(), block,
                                                       block * rate, 1.0 / rate,
                                                       static_cast<long>((std::min(duration, kTactileTraceSeconds) + 1.0) * rate));
  session.add_observer(trace.get());
  return trace;
}

// Prints what runs, runs the session, and returns how a stop signal ended it ("" if none).
std::string run(const Scene& scene, const ServeOptions& opt, const cloth::ClothModel& model,
                const devices::DeviceHandle& dev, const Plan& p, double duration,
                haptics::Session& session, transport::Hub& hub, std::ostream& out) {
  if (!opt.json) {
    out << "scene            " << scene.name << " (" << model.num_triangles() << " triangles)\n";
    out << "device           " << dev.info().name << ", " << dev.info().fingers << " fingers, max "
        << dev.info().max_force << " N\n";
    const char* ticks = scene.haptics.device_clock ? "real time, a tick on each device sample" : "real time";
    out << "clock            " << (opt.realtime ? ticks : "stepped (as fast as possible)")
        << ", " << duration << " s after " << scene.preroll << " s preroll\n";
    for (const auto& n : scene.notes) out << "note             " << n << "\n";
    for (const auto& s : p.stages) out << "stage            " << s << "\n";
    out.flush();
  }
  if (opt.realtime) session.run_realtime(duration);
  else session.run_stepped(duration);
  if (!(opt.stop && opt.stop->load())) return "";
  std::ostringstream os;
  os << "by " << stop_signal_name() << " after " << std::fixed
     << std::setprecision(3) << session.report().sim_time << " s of " << duration << " s";
  hub.post_event("stopping", "server stops on a signal: " + os.str());
  return os.str();
}

// The platform's own timer, in the units and order of the loop's period error above it.
std::string platform_line(const devices::TimerFigures& t) {
  std::ostringstream os;
  os << std::fixed << std::setprecision(1) << "platform timer   p50 " << t.p50_us << ", p99 "
     << t.p99_us << ", p99.9 " << t.p999_us << ", max " << t.max_us << " us; " << t.over_1ms
     << " wake-ups over 1 ms in " << t.ticks << " ticks (during the preroll, " << t.scheduling << ")\n";
  return os.str();
}

// The device's counters, with each part's of a composite device and the record's, as JSON.
void device_json(const Scene& scene, const devices::DeviceHandle& dev, nlohmann::json& j) {
  const auto& dc = dev.device().counters();
  const std::string& record = scene.device.record_path;
  const std::string record_error = dev.last_error();
  j["device"] = dev.info().name;
  j["device_counters"] = {{"samples", dc.samples}, {"dropped", dc.dropped_total()},
                          {"dropped_backlog", dc.dropped_backlog}, {"dropped_stale", dc.dropped_stale},
                          {"dropped_other_sender", dc.dropped_other_sender},
                          {"send_errors", dc.send_errors}, {"tactile_sent", dc.tactile_sent}};
  if (!record.empty())
    j["record"] = {{"path", record}, {"rows", dc.record_rows}, {"dropped", dc.record_dropped},
                   {"error", record_error.empty() ? nlohmann::json(nullptr) : nlohmann::json(record_error)}};
  j["device_parts"] = nlohmann::json::array();
  for (int i = 0; i < dev.device().part_count(); ++i) {
    const devices::Device& part = dev.device().part(i);
    const auto& pc = part.counters();
    const devices::GateCounters* pg = dev.device().part_gate(i);
    j["device_parts"].push_back({{"name", part.info().name}, {"samples", pc.samples},
                                 {"dropped", pc.dropped_total()}, {"dropped_stale", pc.dropped_stale},
                                 {"dropped_other_sender", pc.dropped_other_sender},
                                 {"stale_events", pg ? pg->stale_events : 0}});
  }
}

// The summary as one JSON object: the session's report with the device's, the gate's, the
// cloth's and the transport's counters.
void report_json(const Scene& scene, const devices::DeviceHandle& dev, const Plan& p, haptics::Session& session,
                 const transport::Hub& hub, const haptics::TactileTrace* trace, const std::string& stopped,
                 std::ostream& out) {
  const haptics::SessionReport r = session.report();
  const auto& gc = session.gate().counters();
  const transport::HubStats hs = hub.stats();
  nlohmann::json j = nlohmann::json::parse(r.to_json());
  j["scene"] = scene.name;
  j["stages"] = p.stages;
  j["notes"] = scene.notes;
  device_json(scene, dev, j);
  j["gate"] = {{"non_finite", gc.non_finite}, {"clamped", gc.clamped},
               {"slew_limited", gc.slew_limited}, {"stale_events", gc.stale_events}};
  j["integrator_events"] = session.sim().integrator().events().total();
  if (trace) j["tactile"]["strokes"] = trace->to_json();
  j["trajectory_commands"] = {{"accepted", hs.commands_accepted}, {"rejected", hs.commands_rejected}};
  j["stopped"] = stopped.empty() ? nlohmann::json(nullptr) : nlohmann::json(stopped);
  if (const transport::FoxgloveSink* fox = hub.foxglove()) {
    nlohmann::json f = {{"port", fox->port()}, {"mcap", hub.options().mcap}, {"undecodable", fox->undecodable()}};
    for (int c = 0; c < transport::FoxgloveSink::kChannels; ++c) {
      const auto ch = static_cast<transport::FoxgloveSink::Channel>(c);
      f["messages"][transport::FoxgloveSink::channel_name(ch)] = fox->written(ch);
    }
    j["foxglove"] = f;
  }
  if (p.platform) {
    j["platform_timer"] = p.platform->to_json();
    j["period_error_p99_excess_us"] = r.haptic.period_error_us.quantile(0.99) - p.platform->p99_us;
  }
  out << j.dump() << "\n";
}

// The device's counters as text, and each part's of a composite device.
void device_text(const devices::DeviceHandle& dev, std::ostream& out) {
  const auto& dc = dev.device().counters();
  out << "device counters  samples " << dc.samples << ", dropped " << dc.dropped_total()
      << " (malformed " << dc.dropped_malformed << ", version " << dc.dropped_version
      << ", duplicate " << dc.dropped_duplicate << ", reordered " << dc.dropped_reordered
      << ", out of range " << dc.dropped_out_of_range << ", queued before the session "
      << dc.dropped_backlog << ", stale " << dc.dropped_stale << ", other sender "
      << dc.dropped_other_sender << ")" << (dc.tactile_sent ? ", tactile packets sent " + std::to_string(dc.tactile_sent) : "")
      << "\n";
  for (int i = 0; i < dev.device().part_count(); ++i) {
    const devices::Device& part = dev.device().part(i);
    const auto& pc = part.counters();
    const devices::GateCounters* pg = dev.device().part_gate(i);
    out << "device part " << i << "    " << part.info().name << " (finger " << i << "): samples " << pc.samples
        << ", dropped " << pc.dropped_total() << " (queued before the session " << pc.dropped_backlog
        << ", stale " << pc.dropped_stale << ", other sender " << pc.dropped_other_sender
        << "), watchdog stale events " << (pg ? pg->stale_events : 0) << "\n";
  }
}

// The summary as text, one line a part.
void report_text(const Scene& scene, const devices::DeviceHandle& dev, const Plan& p, haptics::Session& session,
                 const transport::Hub& hub, const haptics::TactileTrace* trace, const std::string& stopped,
                 std::ostream& out) {
  const auto& dc = dev.device().counters();
  const std::string& record = scene.device.record_path;
  const std::string record_error = dev.last_error();
  const auto& gc = session.gate().counters();
  const transport::HubStats hs = hub.stats();
  out << session.report().to_text();
  if (trace) out << trace->to_text();
  if (p.platform) out << platform_line(*p.platform);
  device_text(dev, out);
  out << "safety gate      non-finite " << gc.non_finite << ", clamped " << gc.clamped
      << ", slew-limited " << gc.slew_limited << ", stale events " << gc.stale_events << "\n";
  out << "cloth events     " << session.sim().integrator().events().total() << "\n";
  out << "trajectory cmds  accepted " << hs.commands_accepted << ", rejected " << hs.commands_rejected << "\n";
  if (!record.empty())
    out << "device record    " << record << ": " << dc.record_rows << " rows, " << dc.record_dropped
        << " dropped (buffer full)" << (record_error.empty() ? "" : ", " + record_error) << "\n";
  if (const transport::FoxgloveSink* fox = hub.foxglove())
    out << "foxglove         " << foxglove_counts(*fox) << " messages" << "\n";
  if (!stopped.empty()) out << "stopped          " << stopped << "\n";
}

// The summary: the session's report with the device's, the gate's, the cloth's and the
// transport's counters, as text or one JSON object.
void report(const Scene& scene, const ServeOptions& opt, const devices::DeviceHandle& dev,
            const Plan& p, haptics::Session& session, const transport::Hub& hub,
            const haptics::TactileTrace* trace, const std::string& stopped, std::ostream& out) {
  if (opt.json) report_json(scene, dev, p, session, hub, trace, stopped, out);
  else report_text(scene, dev, p, session, hub, trace, stopped, out);
}

// 1 if the device failed during the session (a driver Error turned its handle Failed), its
// record could not be written, or the transports lost something (the MCAP file not finished,
// LCM log messages not written), each said on stderr; else 0.
int exit_status(const devices::DeviceHandle& dev, const haptics::Session& session,
                const std::string& transport_lost) {
  int rc = 0;
  if (!transport_lost.empty()) {
    std::cerr << "hapticloth-server: " << transport_lost << "\n";
    rc = 1;
  }
  if (dev.failed_since_activation()) {
    std::cerr << "hapticloth-server: device " << dev.info().name << " failed during the session ("
              << session.report().device_errors << " device errors)\n";
    rc = 1;
  }
  if (const std::string record_error = dev.last_error(); !record_error.empty()) {
    std::cerr << "hapticloth-server: " << record_error << "\n";
    rc = 1;
  }
  return rc;
}

}  // namespace

// Plan, build, run, report.
int serve(Scene scene, const ServeOptions& opt, std::ostream& out) {
  const cloth::ClothModel model = build_model(scene);
  check_stop(opt.stop);
  const double duration = opt.duration > 0.0 ? opt.duration : scene.duration;
  // The device first (a UDP rig can start streaming while the cloth settles).
  devices::DeviceHandle dev(opt.make_device ? opt.make_device(scene.device) : devices::make_device(scene.device));
  if (const std::string e = dev.configure(); !e.empty()) throw ConfigError("device: " + e);
  check_stop(opt.stop);
  const auto hub = open_transport(scene, opt, dev, out);
  check_stop(opt.stop);  // set-up done: from the preroll on, a signal winds the run down
  const Plan p = plan(scene, model, dev, opt.realtime, opt.stop);
  haptics::Session session(model, scene.integrator, cloth::make_solver(scene.solver, scene.pcg),
                           p.state, dev, p.session);
  session.set_stop_flag(opt.stop);
  DropReporter drops;
  attach(scene, opt, dev, session, *hub, drops);
  const auto trace = tactile_trace(model, session, duration);
  const std::string stopped = run(scene, opt, model, dev, p, duration, session, *hub, out);
  const std::string lost = hub->finish();  // everything published, the log closed, the MCAP file finished
  report(scene, opt, dev, p, session, *hub, trace.get(), stopped, out);
  return exit_status(dev, session, lost);
}

}  // namespace hapticloth::app
