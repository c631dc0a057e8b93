// hapticloth-bench step --script: the step of a haptic scene under its own device script,
// directly coupled at the haptic period on the stepped clock (no real-time thread shares the
// cores), its time by how many fingertips touch the cloth. What "the cloth runs directly coupled
// at 1 kHz" asks of a step is its time here, with both fingers in contact as with none: a touch,
// a stroke and a lift move the cloth, which a pinch held at rest (step --pinch --settle) does not.
#include <array>

#include "accuracy.hpp"
#include "bench_common.hpp"
#include "haptics/sim/sim_worker.hpp"
#include "mock/trajectory.hpp"

namespace hapticloth::bench {

using nlohmann::json;

namespace {

// One contact state's steps: time, iterations, solves and the kept matrix's work.
struct StepsInContact {
  haptics::Histogram sim_us, integrator_us, assemble_us, solve_us, iterations, elements_formed;
  long steps = 0, solves = 0;

  json to_json() const {
    if (steps == 0) return {{"steps", 0}};
    return {{"steps", steps},
            {"sim_step_us", {{"p50", sim_us.quantile(0.5)}, {"p99", sim_us.quantile(0.99)}, {"max", sim_us.max()}}},
            {"integrator_us", {{"p50", integrator_us.quantile(0.5)}, {"p99", integrator_us.quantile(0.99)}}},
            // Of the integrator's time: the element pass (forces and the matrix) and the solves.
            {"assemble_us", {{"p50", assemble_us.quantile(0.5)}, {"p99", assemble_us.quantile(0.99)}}},
            {"solve_us", {{"p50", solve_us.quantile(0.5)}, {"p99", solve_us.quantile(0.99)}}},
            {"iterations_per_step", {{"mean", iterations.mean()}, {"p99", iterations.quantile(0.99)}}},
            {"solves_per_step", static_cast<double>(solves) / static_cast<double>(steps)},
            {"elements_formed_per_step", elements_formed.mean()}};
  }
};

}  // namespace

json script_step(const app::Scene& scene) {
  if (scene.device.script.empty())
    throw std::invalid_argument("step --script: scene '" + scene.name + "' has no [device] script");
  const cloth::ClothModel model = app::build_model(scene);
  const devices::Trajectory script = devices::load_trajectory(scene.device.script, 2);
  RunConfig direct = default_config(scene);
  direct.dt = 1.0 / scene.haptics.haptic_rate;  // direct coupling steps at the haptic period
  // The haptic scenes' preroll brings the cloth to rest before the session.
  const cloth::ClothState start = settle(scene, model, cloth::rest_state(model), 0.02, scene.preroll);
  MockRig rig(scene, model, start, script, direct, scene.haptics.haptic_rate, scene.haptics.mapping.origin);
  std::array<StepsInContact, 3> by_touching;  // none, one, both fingers in contact
  std::uint64_t steps = 0, revisions = 0;
  rig.session->run_stepped(script.duration(), direct.dt, [&](const haptics::HapticLoop& h, const haptics::SimWorker& w) {
    if (w.steps() == steps) return;
    steps = w.steps();
    const auto& rep = h.last_report();
    StepsInContact& s = by_touching[int(rep.finger[0].in_contact) + int(rep.finger[1].in_contact)];
    const cloth::StepTiming& t = w.integrator().last_timing();
    const auto& ev = w.integrator().events();
    // Whole solves: the first, the re-solves not settled locally, and the confirmations.
    const std::uint64_t rev = ev.contact_revisions - ev.contact_settles + ev.contact_confirmations;
    s.sim_us.add(w.last_step_us());
    s.integrator_us.add(1e3 * t.total_ms);
    s.assemble_us.add(1e3 * t.assemble_ms);
    s.solve_us.add(1e3 * t.solve_ms);
    s.iterations.add(t.iterations);
    s.elements_formed.add(t.refreshed_elements);
    ++s.steps;
    s.solves += 1 + static_cast<long>(rev - revisions);
    revisions = rev;
  });
  const haptics::SessionReport rep = rig.session->report();
  return {{"benchmark", "step-script"},
          {"scene", scene.name},
          {"triangles", model.num_triangles()},
          {"script", scene.device.script},
          {"script_s", script.duration()},
          {"settled_s", scene.preroll},
          {"matrix_refresh", scene.integrator.matrix_refresh},
          {"threads", scene.integrator.assembly_threads},
          {"sim_step_us", {{"p50", rep.sim_step_us.quantile(0.5)}, {"p99", rep.sim_step_us.quantile(0.99)}, {"max", rep.sim_step_us.max()}}},
          {"helper_wait_us", {{"p50", rep.sim_helper_wait_us.quantile(0.5)}, {"p99", rep.sim_helper_wait_us.quantile(0.99)},
                              {"steps_over_100us", rep.sim_helper_wait_us.fraction_at_least(100.0)}}},
          {"fingers_in_contact", {{"none", by_touching[0].to_json()}, {"one", by_touching[1].to_json()},
                                  {"both", by_touching[2].to_json()}}},
          {"contact_revisions", rep.contact_revisions},
          {"contact_settles", rep.contact_settles},
          {"contact_confirmations", rep.contact_confirmations},
          {"max_penetration_mm", rep.max_penetration * 1e3},
          // Local refinement under the fingertips (haptics.refine, step --refine): whether the
          // session made one, and its children and updates (within the steps: stepped clock).
          {"refinement", {{"on", rig.session->sim().refinement() != nullptr},
                          {"builds", rep.refinement_builds},
                          {"updates", rep.refinement_updates}}}};
}

}  // namespace hapticloth::bench
