// hapticloth-bench stability: the stability stress map of the cloth and the haptic coupling.
#include <algorithm>
#include <cmath>
#include <iostream>
#include <random>

#include "accuracy.hpp"
#include "app/run_summary.hpp"
#include "bench_common.hpp"
#include "haptics/contact/geometry.hpp"
#include "mock/trajectory.hpp"

namespace hapticloth::bench {

using nlohmann::json;
using Vec3 = Eigen::Vector3d;

namespace {

// What one run did to the cloth and the fingers.
struct Outcome {
  bool finite = true;
  double max_kinetic = 0.0;      // J
  double max_penetration = 0.0;  // m: how far the cloth reached inside a fingertip proxy
  double max_force = 0.0;        // N, rendered
  double cpu = 0.0, sim = 0.0;
  long contact_ticks = 0;
  long contact_checks = 0, deep_checks = 0;  // global steps with a finger in contact; of them, deeper than tol
  cloth::IntegratorEvents events;
};

// Smallest distance from p to the cloth surface (all triangles: an independent check of the
// proxy, not the broad phase's candidates).
double distance_to_cloth(const Vec3& p, const std::vector<Vec3>& x, const cloth::ClothModel& m) {
  double best = 1e300;
  for (const auto& e : m.elements) {
    const auto cp = haptics::closest_point_triangle(p, x[e.v[0]], x[e.v[1]], x[e.v[2]]);
    best = std::min(best, cp.dist2);
  }
  return std::sqrt(best);
}

// The hanging square at rest for a material scale (6 s from flat, CHOLMOD, dt 5 ms).
cloth::ClothState settle(const app::Scene& sc, const cloth::ClothModel& m) {
  return bench::settle(sc, m, cloth::rest_state(m), 5e-3, sc.preroll);
}

Outcome run(const app::Scene& sc, const cloth::ClothModel& m, const cloth::ClothState& start,
            const devices::Trajectory& script, const RunConfig& c, double duration, double pen_tol) {
  MockRig rig(sc, m, start, script, c, sc.haptics.haptic_rate, sc.haptics.mapping.origin);
  haptics::Session& session = *rig.session;
  const double r = sc.haptics.finger.radius;
  const long every = std::max(1L, std::lround(c.dt * sc.haptics.haptic_rate));
  Outcome o;
  long tick = 0;
  const double t0 = cpu_seconds();
  session.run_stepped(duration, c.dt, [&](const haptics::HapticLoop& h, const haptics::SimWorker& w) {
    const auto& rep = h.last_report();
    for (int f = 0; f < h.fingers(); ++f) {
      const auto& fr = rep.finger[f];
      if (!fr.force.allFinite() || !fr.proxy.allFinite()) o.finite = false;
      o.max_force = std::max(o.max_force, fr.force.norm());
      o.contact_ticks += fr.in_contact;
    }
    // On the tick before each global step the cloth state is one tick ahead of the proxies:
    // compare them there (the coupling's own lag, not the step's).
    if ((tick + 1) % every == 0) {
      const auto& s = w.state();
      for (const auto& p : s.x)
        if (!p.allFinite()) o.finite = false;
      if (o.finite) {
        o.max_kinetic = std::max(o.max_kinetic, cloth::compute_energies(m, s, Vec3::Zero()).kinetic);
        // Direct coupling: the proxy is the fingertip sphere solved with the cloth, checked on
        // every step whether or not it touches (a finger through the cloth touches nothing);
        // the global proxy, as the fingertip reported under local refinement sits deeper than
        // the coarse cloth by design (the dimple it cannot take: docs/contact.md). The multirate
        // path renders its proxy between steps; it is checked while in contact, where its
        // force puts it in the global cloth.
        for (int f = 0; f < h.fingers(); ++f)
          if (rep.finger[f].in_contact || !c.multirate) {
            const Vec3 sphere = c.multirate ? proxy_in_global_cloth(rep.finger[f], w.integrator(), f)
                                            : w.integrator().proxies()[f].x;
            const double pen = r - distance_to_cloth(sphere, s.x, m);
            o.max_penetration = std::max(o.max_penetration, pen);
            ++o.contact_checks;
            o.deep_checks += pen > pen_tol;
          }
      }
    }
    ++tick;
  });
  o.cpu = cpu_seconds() - t0;
  o.sim = duration;
  o.events = session.sim().integrator().events();
  return o;
}

// A stroke at speed v (device frame: the cloth hangs in the y = 0 plane; finger 0 in front):
// in to 4 mm deep, 10 cm sideways, out, then 0.3 s to settle. Finger 1 stays behind, away.
devices::Trajectory stroke(double v) {
  devices::Trajectory t(2);
  const Vec3 a(-0.05, -0.03, 0.0), b(-0.05, -0.004, 0.0), c(0.05, -0.004, 0.0), d(0.05, -0.03, 0.0);
  double time = 0.1;
  t.add(0, 0.0, a);
  t.add(0, time, a);
  for (const Vec3* p : {&b, &c, &d}) {
    const Vec3& prev = t.keys(0).back().p;
    time += (*p - prev).norm() / v;
    t.add(0, time, *p);
  }
  t.add(0, time + 0.3, d);
  t.add(1, 0.0, Vec3(0.0, 0.05, 0.0));
  return t;
}

// Random waypoints for both fingers in a box around the cloth's middle (device frame), joined
// by straight moves at random speeds up to v_max, for `seconds`.
devices::Trajectory random_walk(unsigned seed, double seconds, double v_max) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> ux(-0.08, 0.08), uy(-0.03, 0.03), uz(-0.08, 0.08),
      us(0.05, v_max), uhold(0.0, 0.2);
  devices::Trajectory t(2);
  for (int f = 0; f < 2; ++f) {
    Vec3 p(f == 0 ? -0.04 : 0.04, f == 0 ? -0.03 : 0.03, 0.0);
    double time = 0.0;
    t.add(f, time, p);
    while (time < seconds) {
      const Vec3 q(ux(rng), uy(rng), uz(rng));
      time += std::max((q - p).norm() / us(rng), 1e-3);
      t.add(f, time, q);
      time += uhold(rng);
      t.add(f, time, q);
      p = q;
    }
  }
  return t;
}

double cloth_mass(const cloth::ClothModel& m) { return m.total_mass; }

json verdict(const Outcome& o, double energy_bound, double penetration_tol) {
  std::string why;
  if (!o.finite) why = "non-finite state or force";
  else if (o.events.restores > 0) why = std::to_string(o.events.restores) + " steps abandoned (state restored)";
  else if (o.max_kinetic > energy_bound) why = "kinetic energy " + fmt(o.max_kinetic) + " J > bound " + fmt(energy_bound) + " J";
  else if (o.max_penetration > penetration_tol) why = "penetration " + fmt(o.max_penetration * 1e3) + " mm > " + fmt(penetration_tol * 1e3) + " mm";
  json j = {{"pass", why.empty()},
            {"max_kinetic_j", o.max_kinetic},
            {"energy_bound_j", energy_bound},
            {"max_penetration_mm", o.max_penetration * 1e3},
            {"max_force_n", o.max_force},
            {"contact_ticks", o.contact_ticks},
            {"contact_checks", o.contact_checks},
            {"penetration_over_tol_checks", o.deep_checks},
            {"cpu_s_per_sim_s", o.cpu / o.sim}};
  j.update(app::events_json(o.events));  // the integrator's counters beside the outcome
  if (!why.empty()) j["failure"] = why;
  return j;
}

}  // namespace

// Opens as accuracy() does: the main scene and a progress printer.
json stability(const StabilityOptions& opt) {
  const bool quick = opt.quick;
  app::Scene sc = main_scene(opt.source_dir);
  if (opt.refine) sc.haptics.coupling.refine = *opt.refine;
  const auto say = progress("stability", opt.verbose);
  const std::vector<double> dts = quick ? std::vector<double>{1e-3, 20e-3} : std::vector<double>{1e-3, 5e-3, 20e-3, 40e-3};
  const std::vector<double> scales = quick ? std::vector<double>{1, 1000} : std::vector<double>{1, 10, 100, 1000};
  const std::vector<double> speeds = quick ? std::vector<double>{0.5, 2.0} : std::vector<double>{0.1, 0.5, 2.0};
  const std::vector<double> alphas = quick ? std::vector<double>{0.5, 1.0} : std::vector<double>{0.5, 0.75, 1.0};
  // Tolerances: the proxy may sit inside the cloth by at most a quarter of the fingertip radius;
  // the cloth's kinetic energy may not exceed that of the whole cloth moving at twice the
  // finger's speed plus 2 m/s (a free swing of the 0.5 m cloth reaches about 2 m/s).
  const double pen_tol = 0.25 * sc.haptics.finger.radius;

  json cells = json::array();
  long passed = 0;
  for (double k : scales) {
    const cloth::ClothModel m = grid_model(sc, 22, k);
    say("settling the cloth at stiffness x" + fmt(k));
    const cloth::ClothState start = settle(sc, m);
    const double mass = cloth_mass(m);
    for (double v : speeds) {
      const devices::Trajectory script = stroke(v);
      const double bound = 0.5 * mass * std::pow(2.0 * v + 2.0, 2);
      for (double dt : dts)
        for (double a : alphas) {
          RunConfig c = default_config(sc);
          c.dt = dt, c.alpha = a, c.stiffness_scale = k, c.sweep = "map";
          // The coupling the server runs at this step: direct at the haptic rate, the local
          // patch (4.2) beyond it.
          c.multirate = dt * sc.haptics.haptic_rate > 1.0 + 1e-9;
          say(describe(c) + ", finger " + fmt(v) + " m/s");
          const Outcome o = run(sc, m, start, script, c, script.duration(), pen_tol);
          json j = config_json(c);
          j["stiffness_scale"] = k;
          j["finger_speed"] = v;
          j.update(verdict(o, bound, pen_tol));
          passed += j["pass"].get<bool>();
          cells.push_back(j);
        }
    }
  }

  // Long randomized two-finger trajectories at the scene's defaults (direct coupling): no cloth
  // point more than 0.5 mm inside a fingertip sphere.
  json randoms = json::array();
  {
    const double random_pen_tol = 0.5e-3;
    const cloth::ClothModel m = grid_model(sc, 22);
    const cloth::ClothState start = settle(sc, m);
    const double seconds = opt.random_steps / sc.haptics.haptic_rate;
    const double v_max = 2.0;
    const double bound = 0.5 * cloth_mass(m) * std::pow(2.0 * v_max + 2.0, 2);
    for (unsigned seed : quick ? std::vector<unsigned>{1} : std::vector<unsigned>{1, 2}) {
      RunConfig c = default_config(sc);
      c.sweep = "random";
      say("random trajectory seed " + std::to_string(seed) + ", " + std::to_string(opt.random_steps) + " ticks");
      const Outcome o = run(sc, m, start, random_walk(seed, seconds, v_max), c, seconds, random_pen_tol);
      json j = config_json(c);
      j["seed"] = seed;
      j["ticks"] = opt.random_steps;
      j["finger_speed_max"] = v_max;
      j.update(verdict(o, bound, random_pen_tol));
      randoms.push_back(j);
    }
  }
  return {{"benchmark", "stability"},
          {"quick", quick},
          {"criteria", {{"penetration_tolerance_mm", pen_tol * 1e3},
                        {"random_penetration_tolerance_mm", 0.5},
                        {"energy_bound", "0.5 x cloth mass x (2 x finger speed + 2 m/s)^2"},
                        {"abandoned_steps", 0},
                        {"non_finite", 0}}},
          {"cells", cells},
          {"cells_passed", passed},
          {"random", randoms}};
}

}  // namespace hapticloth::bench
