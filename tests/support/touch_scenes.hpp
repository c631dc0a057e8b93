// The touch checked against physics: a fingertip pressing a pre-tensioned drum (against the
// exact rigid-sphere-on-membrane solution, membrane_reference.hpp) and a free cloth pinched and
// held (against its weight). Both run the whole server path: mock device, stepped session,
// haptic loop, simulation with the fingertip proxies. Shared by the tests and by
// `hapticloth-bench fidelity` (BENCHMARKS.md, "Force fidelity").
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "cloth/mesh.hpp"
#include "cloth/model.hpp"
#include "hal/handle.hpp"
#include "haptics/session.hpp"
#include "mock/mock_device.hpp"
#include "support/fixtures.hpp"
#include "support/membrane_reference.hpp"

namespace hapticloth::test {

using haptics::Vec3;

inline devices::DeviceOptions touch_device_options() {
  devices::DeviceOptions o;
  o.workspace.min = Vec3(-0.3, -0.3, -0.3);
  o.workspace.max = Vec3(0.3, 0.3, 0.3);
  o.max_force = 20.0;
  o.max_stiffness = 5000.0;
  return o;
}

inline cloth::PcgOptions touch_pcg() {
  cloth::PcgOptions pcg;
  pcg.tolerance = 1e-3;  // the scenes' tolerance (BENCHMARKS.md)
  pcg.max_iterations = 300;
  pcg.single_precision_matrix = true;
  return pcg;
}

/// A stepped session around a mock device playing `tr`.
struct TouchRig {
  cloth::ClothModel model;
  devices::DeviceHandle dev;
  std::unique_ptr<haptics::Session> session;
  TouchRig(cloth::ClothModel m, devices::Trajectory tr, const haptics::SessionConfig& sc,
           const cloth::IntegratorConfig& ic, const cloth::ClothState& start,
           const std::string& solver, const cloth::PcgOptions& pcg = touch_pcg(),
           const devices::DeviceOptions& opt = touch_device_options())
      : model(std::move(m)),
        dev(std::make_unique<devices::MockDevice>(opt, std::move(tr))) {
    dev.configure();
    session = std::make_unique<haptics::Session>(model, ic, cloth::make_solver(solver, pcg), start, dev, sc);
  }
};

inline haptics::SessionConfig touch_session(double friction) {
  haptics::SessionConfig sc;
  sc.finger.radius = 0.008;
  sc.finger.stiffness = 800.0;
  sc.finger.damping = 1.0;
  sc.finger.friction = friction;
  sc.gate.slew_rate = 1e4;
  sc.gate.ramp_time = 1e-3;
  return sc;
}

// ---- The drum ------------------------------------------------------------------------------

struct DrumSpec {
  double centre_edge = 0.25e-3;  ///< m, rest edge length at the centre of the graded disc
  double rim_edge = 0.0;         ///< m, largest edge; 0 = max(5 mm, centre_edge)
  /// Local refinement where the mesh does not resolve the patch (Auto: on the multirate path).
  haptics::Refine refine = haptics::Refine::Off;
  MembraneDrum drum{};           ///< Et 1000 N/m, pre-stretch 1.1, rim radius 0.1 m, sphere 8 mm
  double shear = 500.0;          ///< Gt, N/m (isotropic with Poisson 0: Et / 2)
  double density = 0.1;          ///< kg/m^2
  double offset = 0.0;           ///< m, the press's distance from the centre (along x)
  double friction = 0.0;         ///< the fingertip's Coulomb coefficient (frictionless by default)
  double speed = 1e-3;           ///< m/s, the device's descent (quasi-static)
  double device_depth = 4.5e-3;  ///< m the device goes below touch
  double hold = 0.0;             ///< s the device then stays there
  double max_force = 0.0;        ///< N, the safety gate's limit (0: the device's, 20 N)
  std::string solver = "pcg";
  /// In real time (Session::run_realtime, the refinement beside the steps): only the final
  /// depth and force are read.
  bool realtime = false;
  /// s; longer than the haptic period: the multirate path with `model`
  double global_dt = 1e-3;
  haptics::LocalModel model = haptics::LocalModel::Response;
};

/// The session and integrator settings of a touch scene at global step `dt`: above the haptic
/// period the multirate path with local model `m`.
inline void set_global_step(haptics::SessionConfig& sc, cloth::IntegratorConfig& ic, double dt,
                            haptics::LocalModel m) {
  ic.dt = dt;
  sc.rendering = haptics::rendering(dt * sc.haptic_rate > 1.0 + 1e-9, m);
}

struct DrumPoint {
  double depth = 0.0;      ///< m, the proxy sphere's pole below the rim plane
  double force = 0.0;      ///< N, rendered (normal to the drum)
  double reference = 0.0;  ///< N, exact rigid sphere on the membrane
  double error() const { return force / reference - 1.0; }
};

struct DrumResult {
  int triangles = 0;
  std::vector<DrumPoint> points;  ///< at 1, 2, 3 mm
  double onset_depth = 0.0;       ///< m: proxy depth when contact began (0 = geometric touch)
  double max_penetration = 0.0;   ///< m, deepest cloth point inside the sphere
  double final_depth = 0.0;       ///< m, the proxy's depth at the end
  double final_force = 0.0;       ///< N, rendered at the end (normal to the drum)
  double final_sideways = 0.0;    ///< N, rendered at the end across the drum's normal
  haptics::SessionReport report;
};

/// The drum of the membrane reference as a graded disc, frictionless fingertip pressed slowly
/// into its centre, no gravity. The force is read where the proxy's depth crosses 1, 2 and 3 mm.
/// The drum of the membrane reference as a disc meshed as `spec` says (graded from its centre
/// edge to its rim edge), its rim pinned where the pre-stretch puts it, no gravity, and the
/// touch session for it (frictionless fingertip of the drum's sphere radius, the spec's
/// refinement and global step).
struct MembraneDisc {
  cloth::ClothModel model;
  cloth::ClothState start;
  cloth::IntegratorConfig ic;
  haptics::SessionConfig sc;
};
inline MembraneDisc membrane_disc(const DrumSpec& spec) {
  const MembraneDrum& d = spec.drum;
  cloth::DiscSpec ds;
  ds.radius = d.rim_radius / d.prestretch;
  ds.centre_edge = spec.centre_edge;
  ds.rim_edge = spec.rim_edge > 0.0 ? spec.rim_edge : std::max(5e-3, spec.centre_edge);
  const cloth::Mesh mesh = cloth::make_disc(ds);
  cloth::Material mat;
  mat.name = "linear-isotropic";
  mat.areal_density = spec.density;
  mat.weft = cloth::StrainStressCurve::linear(d.Et);
  mat.warp = cloth::StrainStressCurve::linear(d.Et);
  mat.shear = cloth::StrainStressCurve::linear(spec.shear, true);
  for (auto* c : {&mat.weft, &mat.warp, &mat.shear}) c->max_strain = 1.0;
  MembraneDisc m{cloth::build_model(mesh, mat, cloth::disc_rim(mesh)), {}, {}, touch_session(spec.friction)};
  m.start = cloth::rest_state(m.model);
  for (auto& x : m.start.x) x *= d.prestretch;  // pre-stretched, rim pinned there
  m.ic.dt = 1e-3;
  m.ic.gravity = Vec3::Zero();
  m.ic.air_damping = 1.0;
  m.sc.finger.radius = d.sphere_radius;
  m.sc.gate.max_force = spec.max_force;
  m.sc.coupling.refine = spec.refine;
  set_global_step(m.sc, m.ic, spec.global_dt, spec.model);
  return m;
}

/// The force where a press's (depth, force) curve, in the order sampled, first crosses `depth`,
/// interpolated linearly between the two samples around it; 0 if it never does.
inline double force_at_depth(const std::vector<std::pair<double, double>>& curve, double depth) {
  for (size_t i = 1; i < curve.size(); ++i)
    if (curve[i - 1].first < depth && curve[i].first >= depth) {
      const double u = (depth - curve[i - 1].first) / (curve[i].first - curve[i - 1].first);
      return curve[i - 1].second + u * (curve[i].second - curve[i - 1].second);
    }
  return 0.0;
}

inline DrumResult press_drum(const DrumSpec& spec) {
  const MembraneDrum& d = spec.drum;
  MembraneDisc disc = membrane_disc(spec);
  const double r = d.sphere_radius;
  const double top = r + 0.001, bottom = r - spec.device_depth;
  const double t_end = (top - bottom) / spec.speed;
  devices::Trajectory tr(2);
  const Vec3 at(spec.offset, 0.0, 0.0);
  tr.add(0, 0.0, at + Vec3(0, 0, top));
  tr.add(0, t_end, at + Vec3(0, 0, bottom));
  if (spec.hold > 0.0) tr.add(0, t_end + spec.hold, at + Vec3(0, 0, bottom));
  tr.add(1, 0.0, Vec3(0.2, 0.2, 0.2));  // parked away
  TouchRig rig(std::move(disc.model), std::move(tr), disc.sc, disc.ic, disc.start, spec.solver);
  DrumResult res;
  res.triangles = rig.model.num_triangles();
  std::vector<std::pair<double, double>> curve;  // (depth, force)
  bool touched = false;
  if (spec.realtime) {
    // The session's last tick, not the wind-down's after it (which fade the force to zero).
    struct LastTicks final : haptics::SessionObserver {
      std::vector<haptics::HapticReport> reports = std::vector<haptics::HapticReport>(512);
      void on_haptic_tick(const haptics::HapticReport& h, const devices::DeviceState&,
                          const devices::DeviceCommand&) noexcept override {
        reports[h.tick % reports.size()] = h;
      }
    } last;
    rig.session->add_observer(&last);
    rig.session->run_realtime(t_end + spec.hold);
    res.report = rig.session->report();
    const auto& f = last.reports[res.report.haptic.ticks % last.reports.size()].finger[0];
    res.final_depth = -(f.proxy.z() - r);
    res.final_force = f.force.z();
    return res;
  }
  rig.session->run_stepped(t_end + spec.hold, 0.0, [&](const haptics::HapticLoop& h, const haptics::SimWorker&) {
    const auto& f = h.last_report().finger[0];
    const double depth = -(f.proxy.z() - r);
    if (f.in_contact && !touched) {
      touched = true;
      res.onset_depth = depth;
    }
    if (touched) curve.emplace_back(depth, f.force.z());
    res.final_depth = depth;
    res.final_force = f.force.z();
    res.final_sideways = f.force.head<2>().norm();
  });
  res.report = rig.session->report();
  res.max_penetration = res.report.max_penetration;
  for (double target : {1e-3, 2e-3, 3e-3}) {
    DrumPoint p;
    p.depth = target;
    p.force = force_at_depth(curve, target);
    p.reference = spec.offset > 0.0 ? off_centre_force(d, target, spec.offset) : sphere_indentation(d, target).force;
    res.points.push_back(p);
  }
  return res;
}

// ---- Closed press cycles: the energy the rendering gives the user ---------------------------

struct CycleSpec {
  DrumSpec drum{};         ///< the drum, its mesh and global step (its speed and depth unused)
  double frequency = 1.0;  ///< Hz, press-and-release cycles
  int cycles = 4;
  double above = 1e-3;     ///< m, the device's top above geometric touch
  double depth = 3e-3;     ///< m, the device's deepest point below geometric touch
};

struct CycleResult {
  /// J per cycle: the work the force sent to the device did on it (> 0: the user got energy).
  std::vector<double> work_on_user;
  double peak_force = 0.0;  ///< N, largest rendered normal force
  haptics::SessionReport report;
};

/// The device's fingertip pressing along -`out` into the surface point `surface` and back,
/// z(t) = (r + above) - (above + depth) (1 - cos 2 pi f t) / 2 from it, `spec.cycles` times;
/// finger 1 parked at `parked`.
inline devices::Trajectory press_cycles(const CycleSpec& spec, const Vec3& surface, const Vec3& out, double r,
                                        const Vec3& parked) {
  const double travel = spec.above + spec.depth, period = 1.0 / spec.frequency, t_end = spec.cycles * period;
  const Vec3 top = surface + (r + spec.above) * out;
  devices::Trajectory tr(2);
  const int knots = 200;  // per cycle: piecewise linear, 5 ms apart at 1 Hz
  for (int c = 0; c < spec.cycles; ++c)
    for (int k = 0; k < knots; ++k) {
      const double t = (c + static_cast<double>(k) / knots) * period;
      tr.add(0, t, top - travel * 0.5 * (1.0 - std::cos(2.0 * M_PI * spec.frequency * t)) * out);
    }
  tr.add(0, t_end, top);
  tr.add(0, t_end + 0.1, top);
  tr.add(1, 0.0, parked);
  return tr;
}

/// Runs `rig` over the cycles of press_cycles and adds up each cycle's work of the commanded
/// force on the device, sum F_n . (x_n+1 - x_n) (the force held over the tick that follows it);
/// `top` the fingertip's start, `out` the press's outward direction (for the peak force).
inline CycleResult run_cycles(TouchRig& rig, const CycleSpec& spec, const Vec3& top, const Vec3& out,
                              double haptic_rate) {
  const double period = 1.0 / spec.frequency;
  CycleResult res;
  res.work_on_user.assign(spec.cycles, 0.0);
  Vec3 last_x = top, last_f = Vec3::Zero();
  double t = 0.0;
  rig.session->run_stepped(spec.cycles * period, 0.0, [&](const haptics::HapticLoop& h, const haptics::SimWorker&) {
    const Vec3 x = h.device_state().finger[0].position;
    const int c = std::min(spec.cycles - 1, static_cast<int>(t / period));
    res.work_on_user[c] += last_f.dot(x - last_x);
    last_x = x;
    last_f = h.last_command().force[0];
    res.peak_force = std::max(res.peak_force, last_f.dot(out));
    t += 1.0 / haptic_rate;
  });
  res.report = rig.session->report();
  return res;
}

/// The drum pressed and released at its centre by a fingertip moving as
/// z(t) = top - (above + depth) (1 - cos 2 pi f t) / 2, from above touch to `depth` below it
/// and back, `cycles` times. Each cycle's work of the commanded force on the device,
/// sum F_n . (x_n+1 - x_n) (the force held over the tick that follows it).
inline CycleResult cycle_drum(const CycleSpec& spec) {
  MembraneDisc disc = membrane_disc(spec.drum);
  const double r = spec.drum.drum.sphere_radius;
  const Vec3 out = Vec3::UnitZ();
  devices::Trajectory tr = press_cycles(spec, Vec3::Zero(), out, r, Vec3(0.2, 0.2, 0.2));
  TouchRig rig(std::move(disc.model), std::move(tr), disc.sc, disc.ic, disc.start, spec.drum.solver);
  return run_cycles(rig, spec, (r + spec.above) * out, out, disc.sc.haptic_rate);
}

/// The hanging square of the main job (0.5 m of denim, 22 x 22 quads, its top edge pinned),
/// settled at rest for 6 s, pressed at its middle from the front, horizontally, from 1 mm before
/// touch to `spec.depth` past it and back, `spec.cycles` times at `spec.frequency`; the global
/// step and refinement are `spec.drum`'s (its mesh and drum are unused).
inline CycleResult cycle_hanging_square(const CycleSpec& spec) {
  cloth::ClothModel model = square_cloth(denim(), {"top"}, 22, 0.5);
  cloth::IntegratorConfig ic;
  ic.dt = 1e-3;
  ic.gravity = Vec3(0, 0, -9.81);
  ic.air_damping = 0.5;
  cloth::ClothState rest = cloth::rest_state(model);
  {
    cloth::Integrator settle(model, ic, cloth::make_solver("pcg", touch_pcg()));
    for (int k = 0; k < 6000; ++k) settle.step(rest);
    for (auto& v : rest.v) v.setZero();
  }
  int mid = 0;  // the vertex nearest the middle of the hanging cloth
  const Vec3 middle(0.0, 0.25, -0.25);
  for (int i = 0; i < model.num_vertices(); ++i)
    if ((rest.x[i] - middle).norm() < (rest.x[mid] - middle).norm()) mid = i;
  const double r = 0.008;
  const Vec3 surface = rest.x[mid] + Vec3(0.004, 0.0, -0.003);  // off the vertex, inside a triangle
  const Vec3 out(0.0, 1.0, 0.0);  // the press comes from +y
  // Finger 1 parked above the pinned edge.
  devices::Trajectory tr = press_cycles(spec, surface, out, r, Vec3(0.2, 0.2, 0.2));
  haptics::SessionConfig sc = touch_session(0.6);
  sc.coupling.refine = spec.drum.refine;
  set_global_step(sc, ic, spec.drum.global_dt, spec.drum.model);
  TouchRig rig(std::move(model), std::move(tr), sc, ic, rest, "pcg");
  return run_cycles(rig, spec, surface + (r + spec.above) * out, out, sc.haptic_rate);
}

// ---- The hanging square pressed: the coarse scenes against the same scene meshed finer ----

struct SquarePressSpec {
  int quads = 22;  ///< per side of the 0.5 m square (22, 45, 89: the shipped 968, 4050, 15842 triangles)
  /// x and z of the press on the hanging cloth (its plane is y = 0.25 at rest); the fingertip
  /// comes from +y, horizontally
  double x = 0.0, z = -0.25;
  haptics::Refine refine = haptics::Refine::Off;
  double speed = 2e-3;           ///< m/s, the device's approach (quasi-static against the swing)
  double device_depth = 6e-3;    ///< m the device goes past geometric touch
};

struct SquarePressResult {
  int triangles = 0;
  std::vector<std::pair<double, double>> points;  ///< (proxy depth, force) at 1, 2, 3, 5 mm
  double onset_depth = 0.0;  ///< m: the proxy's depth when contact began
};

/// The hanging square of the main job (0.5 m of denim, its top edge pinned) at `spec.quads`,
/// settled 8 s under gravity, pressed slowly from the front with direct coupling: the force
/// normal to the cloth where the proxy's depth past the cloth at rest crosses 1, 2, 3 and 5 mm.
/// The same press on a mesh 8x finer is the discretisation reference (docs/contact.md).
inline SquarePressResult press_hanging_square(const SquarePressSpec& spec) {
  cloth::ClothModel model = square_cloth(denim(), {"top"}, spec.quads, 0.5);
  cloth::IntegratorConfig ic;
  ic.dt = 1e-3;
  ic.gravity = Vec3(0, 0, -9.81);
  ic.air_damping = 0.5;
  cloth::PcgOptions pcg = touch_pcg();
  pcg.max_iterations = 3000;  // the fine scenes' cap (tools/scenes)
  cloth::ClothState rest = cloth::rest_state(model);
  {
    cloth::Integrator settle(model, ic, cloth::make_solver("pcg", pcg));
    for (int k = 0; k < 8000; ++k) settle.step(rest);
    for (auto& v : rest.v) v.setZero();
  }
  // The cloth at rest where the press comes: the plane of the vertex nearest (x, z).
  const Vec3 target(spec.x, 0.25, spec.z);
  int near = 0;
  for (int i = 0; i < model.num_vertices(); ++i)
    if ((rest.x[i] - target).norm() < (rest.x[near] - target).norm()) near = i;
  const Vec3 surface(spec.x, rest.x[near].y(), spec.z), out = Vec3::UnitY();
  const double r = 0.008, top = r + 0.001, bottom = r - spec.device_depth;
  const double t_end = (top - bottom) / spec.speed;
  devices::Trajectory tr(2);
  tr.add(0, 0.0, surface + top * out);
  tr.add(0, t_end, surface + bottom * out);
  tr.add(1, 0.0, Vec3(0.2, 0.2, 0.2));  // parked away
  haptics::SessionConfig sc = touch_session(0.0);
  sc.coupling.refine = spec.refine;
  TouchRig rig(std::move(model), std::move(tr), sc, ic, rest, "pcg", pcg);
  SquarePressResult res;
  res.triangles = rig.model.num_triangles();
  std::vector<std::pair<double, double>> curve;  // (depth, force)
  rig.session->run_stepped(t_end, 0.0, [&](const haptics::HapticLoop& h, const haptics::SimWorker&) {
    const auto& f = h.last_report().finger[0];
    if (!f.in_contact) return;
    const double depth = r - (f.proxy - surface).dot(out);
    if (curve.empty()) res.onset_depth = depth;
    curve.emplace_back(depth, f.force.dot(out));
  });
  for (double depth : {1e-3, 2e-3, 3e-3, 5e-3}) res.points.emplace_back(depth, force_at_depth(curve, depth));
  return res;
}

// ---- A stroke across the drum: the normal force against the exact one along the path -------

struct StrokeSpec {
  DrumSpec drum{};          ///< the drum, its mesh, refinement and global step
  double depth = 3e-3;      ///< m, the device's depth below touch while it strokes
  double from = -0.04, to = 0.04;  ///< m, along x through the centre
  double speed = 0.02;      ///< m/s along the stroke
  double friction = 0.0;
};

struct StrokeSample {
  double x = 0.0;       ///< m, the fingertip's offset along the stroke
  double depth = 0.0;   ///< m, the proxy's depth below touch
  double normal = 0.0;  ///< N, the rendered force's vertical part
  double along = 0.0;   ///< N, its part along the stroke (+x)
  double reference = 0.0;  ///< N, the exact force at that depth and offset (off_centre_force)
  /// N: the rendered force along the contact's shaded normal, and its magnitude across it
  /// (friction), with whether every contact point slides (FingerReport::slipping).
  double contact_normal = 0.0, tangential = 0.0;
  bool slipping = false;
  double error() const { return normal / reference - 1.0; }
};

/// The drum pressed `depth` at `from`, then stroked to `to` at `speed`; every 50th tick of the
/// stroke is sampled (the reference is a few shooting solves per sample).
inline std::vector<StrokeSample> stroke_drum(const StrokeSpec& spec) {
  const MembraneDrum& d = spec.drum.drum;
  MembraneDisc disc = membrane_disc(spec.drum);
  disc.sc.finger.friction = spec.friction;
  const double r = d.sphere_radius, z = r - spec.depth;
  const double press = 0.5, settle = 0.3, t_stroke = std::abs(spec.to - spec.from) / spec.speed;
  devices::Trajectory tr(2);
  tr.add(0, 0.0, Vec3(spec.from, 0.0, r + 0.001));
  tr.add(0, press, Vec3(spec.from, 0.0, z));
  tr.add(0, press + settle, Vec3(spec.from, 0.0, z));
  tr.add(0, press + settle + t_stroke, Vec3(spec.to, 0.0, z));
  tr.add(1, 0.0, Vec3(0.2, 0.2, 0.2));  // parked away
  TouchRig rig(std::move(disc.model), std::move(tr), disc.sc, disc.ic, disc.start, spec.drum.solver);
  std::vector<StrokeSample> out;
  long k = 0;
  rig.session->run_stepped(press + settle + t_stroke, 0.0, [&](const haptics::HapticLoop& h, const haptics::SimWorker&) {
    const auto& f = h.last_report().finger[0];
    if (h.last_report().time < press + settle || !f.in_contact || ++k % 50 != 0) return;
    StrokeSample s;
    s.x = f.position.x();
    s.depth = -(f.proxy.z() - r);
    s.normal = f.force.z();
    s.along = f.force.x();
    s.reference = off_centre_force(d, s.depth, std::abs(f.proxy.x()));
    s.contact_normal = f.force.dot(f.normal);
    s.tangential = (f.force - s.contact_normal * f.normal).norm();
    s.slipping = f.slipping;
    out.push_back(s);
  });
  return out;
}

// ---- The handkerchief ----------------------------------------------------------------------

struct PinchSpec {
  int quads = 30;             ///< per side of the 0.2 m square
  double size = 0.2;          ///< m
  double squeeze = 0.002;     ///< m, each fingertip's device position inside the cloth
  double friction = 0.6;
  double hold = 6.0;          ///< s
  std::string solver = "cholmod";
  double global_dt = 1e-3;    ///< s (see DrumSpec)
  haptics::LocalModel model = haptics::LocalModel::Response;
  /// The fingertips are squeezed from the first tick (the cloth is inside them when the
  /// simulation first sees them), instead of closing over the first 50 ms.
  bool engaged_from_start = false;
  haptics::Refine refine = haptics::Refine::Auto;
  /// Hanging: the square hangs in the xz plane and is pinched from either side (+-y) 2 cm below
  /// the middle of its top edge, so that only friction holds it up (a cloth pinched from above
  /// and below can drape over the lower fingertip instead).
  bool from_the_sides = false;
};

struct PinchResult {
  double weight = 0.0;         ///< N, m g
  double carried = 0.0;        ///< N, mean upward force the fingers put on the cloth, last second
  double centre_offset = 0.0;  ///< m, cloth centre from the pinch point at the end
  double centre_drop = 0.0;    ///< m, how far the cloth's centre went down from its start
  bool in_contact_at_end = false;  ///< either fingertip touching the cloth on the last tick
  double max_penetration = 0.0;
  /// N: largest difference, over the steps, between the force the cloth got from the fingers
  /// (from its momentum balance: sum m dv / h - m g + air drag) and minus the rendered forces.
  double third_law = 0.0;
  haptics::SessionReport report;
  double error() const { return carried / weight - 1.0; }
};

/// A free square of denim (no pins, gravity) pinched at its centre from above and below (or, hanging,
/// from the sides near its top edge) and held still. Carried = minus the vertical sum of the
/// rendered forces.
inline PinchResult pinch_handkerchief(const PinchSpec& spec) {
  cloth::GridSpec g;
  g.width = g.height = spec.size;
  g.nx = g.ny = spec.quads;
  g.origin = {-spec.size / 2, -spec.size / 2, 0.0};
  // The pinch point, off the vertices (inside a triangle), and the direction the first
  // fingertip presses from.
  Vec3 at(0.0011, 0.0007, 0.0), from = Vec3::UnitZ();
  if (spec.from_the_sides) {
    g.plane = cloth::GridPlane::XZ;
    g.origin = {-spec.size / 2, 0.0, -spec.size};
    at = Vec3(0.0011, 0.0, -0.0207);
    from = Vec3::UnitY();
  }
  const cloth::Mesh mesh = cloth::make_grid(g);
  cloth::ClothModel model = cloth::build_model(mesh, denim(), {});
  const cloth::ClothState start = cloth::rest_state(model);
  cloth::IntegratorConfig ic;
  ic.dt = 1e-3;
  ic.gravity = Vec3(0, 0, -9.81);
  ic.air_damping = 0.5;
  const double r = 0.008, s = spec.squeeze;
  devices::Trajectory tr(2);
  const double closing = spec.engaged_from_start ? 0.0 : 0.05;
  if (closing > 0.0) tr.add(0, 0.0, at + r * from);
  tr.add(0, closing, at + (r - s) * from);
  tr.add(0, spec.hold, at + (r - s) * from);
  if (closing > 0.0) tr.add(1, 0.0, at - r * from);
  tr.add(1, closing, at - (r - s) * from);
  tr.add(1, spec.hold, at - (r - s) * from);
  haptics::SessionConfig sc = touch_session(spec.friction);
  sc.coupling.refine = spec.refine;
  set_global_step(sc, ic, spec.global_dt, spec.model);
  TouchRig rig(std::move(model), std::move(tr), sc, ic, start, spec.solver);
  int centre = 0;  // the vertex nearest the pinch point
  for (int i = 0; i < rig.model.num_vertices(); ++i)
    if ((start.x[i] - at).norm() < (start.x[centre] - at).norm()) centre = i;
  PinchResult res;
  res.weight = rig.model.total_mass * 9.81;
  double sum = 0.0;
  long n = 0;
  const cloth::ClothModel& m = rig.model;
  auto momentum = [&](const cloth::ClothState& st) {
    Vec3 p = Vec3::Zero();
    for (int i = 0; i < m.num_vertices(); ++i) p += m.mass[i] * st.v[i];
    return p;
  };
  Vec3 p_prev = momentum(start);
  std::uint64_t steps = 0;
  rig.session->run_stepped(spec.hold, 0.0, [&](const haptics::HapticLoop& h, const haptics::SimWorker& sim) {
    // Newton's third law, step by step: what the cloth's momentum says it got from the fingers
    // against what the fingers render (before the device's safety gate).
    const auto& rep = h.last_report();
    if (rep.time >= spec.hold - 1.0) {
      sum += -(rep.finger[0].force.z() + rep.finger[1].force.z());
      ++n;
    }
    if (sim.steps() == steps) return;
    steps = sim.steps();
    const cloth::ClothState& st = sim.state();
    const Vec3 p_now = momentum(st);
    Vec3 drag = Vec3::Zero();
    for (int i = 0; i < m.num_vertices(); ++i) drag += ic.air_damping * m.vertex_area[i] * st.v[i];
    const Vec3 from_fingers = (p_now - p_prev) / ic.dt - m.total_mass * ic.gravity + drag;
    p_prev = p_now;
    Vec3 rendered = Vec3::Zero();
    for (int f = 0; f < 2; ++f) rendered += sim.last_snapshot().proxy[f].force;
    res.third_law = std::max(res.third_law, (from_fingers + rendered).norm());
  });
  res.carried = n ? sum / n : 0.0;
  res.centre_offset = (rig.session->sim().state().x[centre] - at).norm();
  res.centre_drop = start.x[centre].z() - rig.session->sim().state().x[centre].z();
  const auto& last = rig.session->haptics().last_report();
  res.in_contact_at_end = last.finger[0].in_contact || last.finger[1].in_contact;
  res.report = rig.session->report();
  res.max_penetration = res.report.max_penetration;
  return res;
}

// --- the drum rig of the session tests (tests/haptics/test_session.cpp, test_haptic_loop.cpp) ---

// A horizontal 0.3 m square (z = 0) pinned on its four edges, 20 x 20 quads.
inline cloth::ClothModel drum(int n = 20, double size = 0.3) { return denim_drum(n, size); }

inline cloth::IntegratorConfig sim_config(double dt = 0.001) {
  cloth::IntegratorConfig c;
  c.dt = dt;
  c.alpha = 1.0;
  c.gravity = Vec3::Zero();
  c.air_damping = 2.0;
  return c;
}

// Drums start pre-stretched by 3% (a membrane without bending has no out-of-plane stiffness
// when slack; tension gives it one, as on an embroidery hoop).
inline cloth::ClothState drum_start_state(const cloth::ClothModel& m) {
  cloth::ClothState s = cloth::rest_state(m);
  int pinned = 0;
  for (int i = 0; i < m.num_vertices(); ++i) pinned += m.pinned[i];
  const int n = static_cast<int>(std::lround(std::sqrt(m.num_vertices()))) - 1;  // quads a side
  if (pinned == 4 * n)  // every boundary vertex: a drum
    for (auto& x : s.x) x.head<2>() *= 1.03;
  return s;
}

/// A drum (or any cloth) with the mock device following `tr`, direct coupling, CHOLMOD, stepped.
struct DrumRig {
  cloth::ClothModel model;
  devices::DeviceHandle dev;
  std::unique_ptr<haptics::Session> session;
  DrumRig(cloth::ClothModel m, devices::Trajectory tr, haptics::SessionConfig sc = {},
      cloth::IntegratorConfig ic = sim_config(), const devices::DeviceOptions& opt = touch_device_options())
      : model(std::move(m)),
        dev(std::make_unique<devices::MockDevice>(opt, std::move(tr))) {
    EXPECT_EQ(dev.configure(), "");
    sc.gate.slew_rate = 1e4;
    sc.gate.ramp_time = 1e-3;
    session = std::make_unique<haptics::Session>(model, ic, cloth::make_cholmod_solver(),
                                                 drum_start_state(model), dev, sc);
  }
};

// ---- Tactile ---------------------------------------------------------------------------------

/// The touch device with a HAPTEX-like tactile display: vibration at 4 kHz, 6 x 4 pins at 2 mm.
inline devices::DeviceOptions tactile_device_options() {
  devices::DeviceOptions o = touch_device_options();
  o.tactile.vibration_rate = 4000;
  o.tactile.pin_rows = 6;
  o.tactile.pin_cols = 4;
  o.tactile.pin_pitch = 0.002;
  return o;
}

/// `m` with a sine weave: period `weft` (m) along u, `warp` along v, amplitude 10 um, friction
/// MIU 0.3 (MMD 0.02).
inline cloth::ClothModel with_weave(cloth::ClothModel m, double weft = 0.5e-3, double warp = 0.8e-3) {
  cloth::Surface& s = m.material.surface;
  s.weft = cloth::weave_profile(weft, 10e-6, cloth::WeaveShape::Sine);
  s.warp = cloth::weave_profile(warp, 10e-6, cloth::WeaveShape::Sine);
  s.miu = 0.3;
  s.mmd = 0.02;
  s.source = "test weave";
  s.normalize_friction();
  return m;
}

// Two fingers: finger 0 follows `f0`, finger 1 parked far from the cloth.
inline devices::Trajectory one_finger(const std::vector<std::pair<double, Vec3>>& f0) {
  devices::Trajectory t(2);
  for (const auto& [time, p] : f0) t.add(0, time, p);
  t.add(1, 0.0, Vec3(0.15, 0.15, 0.15));
  return t;
}

}  // namespace hapticloth::test
