// Local refinement under the fingertips (server/haptics/refinement/local_refinement.hpp,
// refined_contact.hpp): the drum press on uniform meshes too coarse for the contact patch,
// against the exact membrane solution (membrane_reference.hpp).
#include <cstdio>

#include "haptics/refinement/refined_contact.hpp"
#include "support/touch_scenes.hpp"

using namespace hapticloth;

// Uniform meshes of 2-25 mm edges against an 8 mm fingertip (the edges of every shipped scene),
// pressed 1-3 mm deep: within 3% of the exact solution (itself what the fine-mesh drum matches
// to 0.2-1.3%), and the contact begins within 0.1 mm of geometric touch.
TEST(LocalRefinement, DrumPressOnAnyMeshMatchesMembraneTheory) {
  for (double h : {2e-3, 4e-3, 8e-3, 12e-3, 25e-3}) {
    test::DrumSpec spec;
    spec.centre_edge = spec.rim_edge = h;
    spec.speed = 4e-3;
    spec.device_depth = 3.6e-3;
    const test::DrumResult off = test::press_drum(spec);  // the same press without refinement
    spec.refine = haptics::Refine::On;
    const test::DrumResult r = test::press_drum(spec);
    std::printf("edge %4.1f mm (%5d triangles), force error at 1/2/3 mm: off", h * 1e3, r.triangles);
    for (const auto& p : off.points) std::printf(" %+.2f%%", 100.0 * p.error());
    std::printf(", on");
    for (const auto& p : r.points) std::printf(" %+.2f%%", 100.0 * p.error());
    std::printf("; onset %.3f mm; sim step p50 %.0f us, p99 %.0f us (off: %.0f, %.0f)\n", r.onset_depth * 1e3,
                r.report.sim_step_us.quantile(0.5), r.report.sim_step_us.quantile(0.99),
                off.report.sim_step_us.quantile(0.5), off.report.sim_step_us.quantile(0.99));
    for (const auto& p : r.points) EXPECT_LE(std::abs(p.error()), 0.03) << h << " " << p.depth;
    EXPECT_LE(std::abs(r.onset_depth), 1e-4) << h;
  }
}

// The same press with fingertips of 5 and 12 mm radius, and with the 8 mm one pressed 3 cm off the
// centre (the reference there: the exact centred solution with the disc's Green function for the
// offset, membrane_reference.hpp off_centre_force), on the same uniform meshes: within 3%.
TEST(LocalRefinement, DrumPressWithOtherFingertipsAndOffCentre) {
  struct Case {
    double radius, offset;
  };
  for (const Case c : {Case{5e-3, 0.0}, Case{12e-3, 0.0}, Case{8e-3, 0.03}})
    for (double h : {2e-3, 4e-3, 8e-3, 12e-3, 25e-3}) {
      test::DrumSpec spec;
      spec.centre_edge = spec.rim_edge = h;
      spec.drum.sphere_radius = c.radius;
      spec.offset = c.offset;
      spec.speed = 4e-3;
      spec.device_depth = 3.6e-3;
      spec.refine = haptics::Refine::On;
      const test::DrumResult r = test::press_drum(spec);
      std::printf("fingertip %4.1f mm, %2.0f mm off centre, edge %4.1f mm: force error at 1/2/3 mm", c.radius * 1e3,
                  c.offset * 1e3, h * 1e3);
      for (const auto& p : r.points) std::printf(" %+.2f%%", 100.0 * p.error());
      std::printf("; onset %.3f mm\n", r.onset_depth * 1e3);
      for (const auto& p : r.points)
        EXPECT_LE(std::abs(p.error()), 0.03) << c.radius << " " << c.offset << " " << h << " " << p.depth;
      EXPECT_LE(std::abs(r.onset_depth), 1e-4) << c.radius << " " << c.offset << " " << h;
    }
}

// In real time the children settle on a worker thread beside the steps (BackgroundRefinement),
// and each step takes the compliance the worker last gave. A press on the uniform 12 mm drum,
// held: the force at the held depth is within 3% of the exact solution, as within the steps.
TEST(LocalRefinement, BesideTheStepsInRealTimeMatchesMembraneTheory) {
  test::DrumSpec spec;
  spec.centre_edge = spec.rim_edge = 12e-3;
  spec.speed = 4e-3;
  spec.device_depth = 3.0e-3;
  spec.hold = 0.5;
  spec.refine = haptics::Refine::On;
  spec.realtime = true;
  const test::DrumResult r = test::press_drum(spec);
  const double reference = test::sphere_indentation(spec.drum, r.final_depth).force;
  std::printf("real time, refinement beside the steps: %.3f mm deep, %.4f N vs %.4f N (%+.2f%%); %llu children, "
              "%llu updates; sim step p50 %.0f us, p99 %.0f us\n", r.final_depth * 1e3, r.final_force, reference,
              100.0 * (r.final_force / reference - 1.0), static_cast<unsigned long long>(r.report.refinement_builds),
              static_cast<unsigned long long>(r.report.refinement_updates), r.report.sim_step_us.quantile(0.5),
              r.report.sim_step_us.quantile(0.99));
  EXPECT_TRUE(r.report.refinement_beside_steps);
  EXPECT_GT(r.report.refinement_updates, 10u);
  EXPECT_GT(r.final_depth, 1e-3);
  EXPECT_LE(std::abs(r.final_force / reference - 1.0), 0.03);
}

// The multirate path (the response model at 10 and 20 ms global steps) refines the same way: the
// compliance of the child goes in series with the coupling the step solves with, and the force
// between steps follows the step's response with that spring (ResponseContact). Uniform 8 and
// 25 mm meshes, pressed 1-3 mm deep: within 3% of the exact solution.
TEST(LocalRefinement, MultiratePressOnCoarseMeshesMatchesMembraneTheory) {
  for (double dt : {1e-2, 2e-2})
    for (double h : {8e-3, 25e-3}) {
      test::DrumSpec spec;
      spec.centre_edge = spec.rim_edge = h;
      spec.speed = 4e-3;
      spec.device_depth = 3.6e-3;
      spec.global_dt = dt;
      const test::DrumResult off = test::press_drum(spec);
      spec.refine = haptics::Refine::On;
      const test::DrumResult r = test::press_drum(spec);
      std::printf("global step %2.0f ms, edge %4.1f mm, force error at 1/2/3 mm: off", dt * 1e3, h * 1e3);
      for (const auto& p : off.points) std::printf(" %+.2f%%", 100.0 * p.error());
      std::printf(", on");
      for (const auto& p : r.points) std::printf(" %+.2f%%", 100.0 * p.error());
      std::printf("; onset %.3f mm\n", r.onset_depth * 1e3);
      for (const auto& p : r.points) EXPECT_LE(std::abs(p.error()), 0.03) << dt << " " << h << " " << p.depth;
    }
}

// The same stroke with friction 0.6 (every sample slides): the tangential force the device
// renders against mu times its normal force, both taken about the contact's shaded normal, on
// the 12 and 25 mm meshes with and without refinement. The series compliance must not change
// the Coulomb ratio: over the stroke it is within 2% of mu either way. Single samples depart
// further (up to 6-10%, and as much without refinement: the contact points' normals spread over
// the dimple, so their summed friction is not mu times their summed normal force at every
// instant); the mean is what a sliding finger integrates.
TEST(LocalRefinement, FrictionStrokeKeepsTheCoulombRatio) {
  for (double h : {12e-3, 25e-3})
    for (const haptics::Refine refine : {haptics::Refine::Off, haptics::Refine::On}) {
      test::StrokeSpec spec;
      spec.drum.centre_edge = spec.drum.rim_edge = h;
      spec.drum.refine = refine;
      spec.friction = 0.6;
      const std::vector<test::StrokeSample> s = test::stroke_drum(spec);
      double mean = 0.0, worst = 0.0, normal_error = 0.0;
      int sliding = 0;
      for (const auto& p : s) {
        normal_error += p.error() / s.size();
        if (!p.slipping) continue;
        const double e = p.tangential / (spec.friction * p.contact_normal) - 1.0;
        mean += e;
        worst = std::max(worst, std::abs(e));
        ++sliding;
      }
      mean /= std::max(sliding, 1);
      std::printf("edge %4.1f mm, refinement %s, friction 0.6: tangential / (mu N) - 1 over %d sliding samples of "
                  "%zu: mean %+.2f%%, worst %.2f%%; normal force against the exact one: mean %+.2f%%\n", h * 1e3,
                  haptics::to_string(refine), sliding, s.size(), 100 * mean, 100 * worst, 100 * normal_error);
      EXPECT_GE(sliding, static_cast<int>(s.size()) - 2) << h;
      EXPECT_LE(std::abs(mean), 0.02) << h << " " << haptics::to_string(refine);
      if (refine == haptics::Refine::On) {
        EXPECT_LE(std::abs(normal_error), 0.03) << h;
      }
    }
}

// A pinch is a sandwich, not a dimple: the two fingertips and the cloth between them move
// together, so the refinement puts in series with each coupling only the sandwich's squeeze
// (LocalRefinement::series_depth). The light pinch of test_fingertip_contact (10 mm elements,
// 0.5 mm squeeze, mu 0.2, 3 s) holds the cloth the same with refinement as without: its weight
// within 1%, its centre within 0.5 mm of where it stays without (1.7 mm off the pinch). Taken as
// each finger's own depth, the lower fingertip got 1.3 mm of compliance, the upper one lost the
// cloth, and the centre drifted 6.2 mm.
TEST(LocalRefinement, APinchIsASandwichNotADimple) {
  test::PinchSpec spec{.quads = 20, .squeeze = 0.0005, .friction = 0.2, .hold = 3.0};
  const test::PinchResult off = test::pinch_handkerchief(spec);
  spec.refine = haptics::Refine::On;
  const test::PinchResult on = test::pinch_handkerchief(spec);
  std::printf("light pinch: weight %.4f N; off: carried %+.2f%%, centre %.2f mm off; on: carried %+.2f%%, centre %.2f "
              "mm off, %llu children\n", on.weight, 100 * off.error(), off.centre_offset * 1e3, 100 * on.error(),
              on.centre_offset * 1e3, static_cast<unsigned long long>(on.report.refinement_builds));
  EXPECT_GT(on.report.refinement_builds, 0u);
  EXPECT_LE(std::abs(on.error()), 0.01);
  EXPECT_NEAR(on.centre_offset, off.centre_offset, 0.5e-3);
}

// What a viewer gets of the children (SessionObserver::on_refined, cloth_state_t's refined
// fields): a press into the uniform 25 mm drum and back out. While pressed, the session shows a
// child standing in for the touched triangles, deeper than the global mesh can dip (the dimple it
// resolves), with every triangle indexing its own vertices; once the fingertip has left, none.
TEST(LocalRefinement, AViewerSeesTheChildWhileTheFingertipPresses) {
  struct Viewer : haptics::SessionObserver {
    int calls = 0, shown = 0;
    double deepest = 0.0, global_deepest = 0.0;
    bool indexed = true;
    haptics::RefinedRegions last;
    const cloth::ClothState* cloth = nullptr;
    void on_refined(const haptics::RefinedRegions& r) noexcept override {
      ++calls;
      last = r;
      if (r.empty()) return;
      ++shown;
      for (const auto& t : r.triangles)
        for (int v : t) indexed = indexed && v >= 0 && v < static_cast<int>(r.x.size());
      for (const auto& x : r.x) deepest = std::min(deepest, x.z());
      for (const auto& x : cloth->x) global_deepest = std::min(global_deepest, x.z());
    }
  };
  test::DrumSpec spec;
  spec.centre_edge = spec.rim_edge = 25e-3;
  spec.refine = haptics::Refine::On;
  test::MembraneDisc disc = test::membrane_disc(spec);
  const double r = spec.drum.sphere_radius;
  devices::Trajectory tr(2);
  using Vec3 = Eigen::Vector3d;
  tr.add(0, 0.0, Vec3(0, 0, r + 1e-3));
  tr.add(0, 0.5, Vec3(0, 0, r - 3e-3));
  tr.add(0, 1.0, Vec3(0, 0, r + 2e-3));
  tr.add(0, 1.2, Vec3(0, 0, r + 2e-3));
  tr.add(1, 0.0, Vec3(0.2, 0.2, 0.2));
  test::TouchRig rig(std::move(disc.model), std::move(tr), disc.sc, disc.ic, disc.start, spec.solver);
  Viewer v;
  v.cloth = &rig.session->sim().state();
  rig.session->add_observer(&v);
  rig.session->run_stepped(1.2, 0.0, [](const haptics::HapticLoop&, const haptics::SimWorker&) {});
  std::printf("viewer: %d updates of the children, %d showing one; deepest child vertex %.3f mm, global %.3f mm\n",
              v.calls, v.shown, v.deepest * 1e3, v.global_deepest * 1e3);
  EXPECT_GT(v.shown, 100);
  EXPECT_TRUE(v.indexed);
  EXPECT_LT(v.deepest, v.global_deepest - 0.3e-3);  // the child resolves the dimple the mesh cannot
  EXPECT_TRUE(v.last.empty());
  EXPECT_TRUE(v.last.region.empty());
}

// The child alone: the whole pre-stretched drum refined around its centre (its border is the
// pinned rim), the fingertip pushed in with the exact solution's force at 1, 2 and 3 mm: the
// child's depth is the exact depth.
TEST(RefinedContact, WholeDrumChildCarriesTheExactForceAtTheExactDepth) {
  const test::MembraneDrum d;
  cloth::DiscSpec ds;
  ds.radius = d.rim_radius / d.prestretch;
  ds.centre_edge = ds.rim_edge = 23e-3;
  const cloth::Mesh mesh = cloth::make_disc(ds);
  cloth::Material mat;
  mat.areal_density = 0.1;
  mat.weft = cloth::StrainStressCurve::linear(d.Et);
  mat.warp = cloth::StrainStressCurve::linear(d.Et);
  mat.shear = cloth::StrainStressCurve::linear(500.0, true);
  for (auto* c : {&mat.weft, &mat.warp, &mat.shear}) c->max_strain = 1.0;
  const cloth::ClothModel g = cloth::build_model(mesh, mat, cloth::disc_rim(mesh));
  std::vector<haptics::Vec3> gx = g.rest_positions;
  for (auto& x : gx) x *= d.prestretch;
  haptics::MeshRefiner refiner(g);
  haptics::ClothPoint at;
  at.tri = 0;
  for (int t = 0; t < g.num_triangles(); ++t)
    for (int k = 0; k < 3; ++k)
      if (g.rest_positions[g.triangles[t][k]].norm() < 1e-9) at.tri = t, at.b = {0, 0, 0}, at.b[k] = 1.0;
  haptics::RefineSpec spec;
  spec.finest = 1e-3;
  spec.reach = 0.2;
  haptics::ChildLaw law;
  haptics::RefinedContact child(refiner.refine(at, spec), mat, haptics::Vec3::Zero(), law);
  child.follow(gx);
  std::printf("child: %d vertices, %zu held\n", child.model().num_vertices(), child.mesh().held.size());
  for (double depth : {1e-3, 2e-3, 3e-3}) {
    std::array<haptics::ChildFinger, haptics::kMaxFingers> f{};
    f[0].in = true;
    f[0].centre = haptics::Vec3(0, 0, law.radius);
    f[0].normal = haptics::Vec3(0, 0, 1);
    f[0].force = test::sphere_indentation(d, depth).force;
    const double left = child.settle(f, 60);
    std::printf("depth %.1f mm: force %.4f N, child depth %.4f mm (%+.2f%%), left %.2g N\n", depth * 1e3,
                f[0].force, child.extra_depth(0) * 1e3, 100.0 * (child.extra_depth(0) / depth - 1.0), left);
    // 1 mm child edges at the contact: the fine-mesh drum's own discretisation error (1-3%
    // in force, a third of that in depth on this log-like curve) bounds it.
    EXPECT_LE(std::abs(child.extra_depth(0) / depth - 1.0), 0.015) << depth;
    EXPECT_LE(left, 1e-5 * f[0].force) << depth;
  }
}

// A press straight down with friction 0.6, between the global vertices of a 12 mm mesh (4 mm
// from the centre vertex), held. The flat drum pushes a fingertip there back along its own
// normal: sideways by the slope of the membrane at the press, which the disc's Green function
// puts far under 1% of the force 4 mm from the centre. The coarse facets are tilted there, and
// the refined compliance acts along one axis while the coupling holds the fingertip stiffly
// across it: taken along the facets' normal, the device's straight descent crossed the axis and
// the sticking contact rendered that as a sideways force (here 2.2% of the normal force against
// the unrefined mesh's 0.6%; 8.5% in `hapticloth-bench accuracy`'s press); along the refined
// membrane's normal (RefinedContact::push) it stays within the unrefined mesh's own (0.55%).
TEST(LocalRefinement, PressStraightDownIsNotPushedSideways) {
  double unrefined = 0.0;
  for (const haptics::Refine refine : {haptics::Refine::Off, haptics::Refine::On}) {
    test::DrumSpec spec;
    spec.centre_edge = spec.rim_edge = 12e-3;
    spec.offset = 4e-3;
    spec.friction = 0.6;
    spec.device_depth = 3e-3;
    spec.speed = 4e-3;
    spec.hold = 0.3;
    spec.refine = refine;
    const test::DrumResult r = test::press_drum(spec);
    const double ratio = r.final_sideways / r.final_force;
    std::printf("press straight down 4 mm from the centre, 12 mm edges, friction 0.6, refinement %s: %.4f N "
                "down, %.5f N sideways (%.2f%%)\n", haptics::to_string(refine), r.final_force, r.final_sideways,
                100 * ratio);
    ASSERT_GT(r.final_force, 0.05);
    if (refine == haptics::Refine::Off) unrefined = ratio;
    else EXPECT_LE(ratio, std::max(0.01, unrefined)) << "the refined press renders a sideways force of its own";
  }
}

// A frictionless stroke across the drum at constant device depth (3 mm), through the centre from
// 4 cm on one side to 4 cm on the other at 20 mm/s: the normal force along the path against the
// exact one at the proxy's depth and offset (off_centre_force). Without refinement the 12 mm
// mesh is 41% too stiff on average and the force ripples with the facets; with it every sample
// is within the 3% the press is held to (the child's own discretisation at grading 1.0: the
// press on these meshes is 1-2.5% stiff), across the global vertices the contact crosses. The
// facets are what the ripple measures: how far a sample's error departs from the stroke's mean
// error (a smooth surface keeps it constant along the path): without the child 25.5% on the
// 12 mm mesh; with it 0.67% there and 1.62% on the 25 mm mesh, where the child, re-centred at a
// tenth of its reach, still leaves dips of its own (the 1% of issue 35 is not met there).
TEST(LocalRefinement, StrokeFollowsTheExactForceAlongThePath) {
  struct Case {
    double edge;
    haptics::Refine refine;
  };
  for (const Case c : {Case{12e-3, haptics::Refine::Off}, Case{12e-3, haptics::Refine::On},
                       Case{25e-3, haptics::Refine::On}}) {
    test::StrokeSpec spec;
    spec.drum.centre_edge = spec.drum.rim_edge = c.edge;
    spec.drum.refine = c.refine;
    const std::vector<test::StrokeSample> s = test::stroke_drum(spec);
    double worst = 0.0, mean = 0.0, drag = 0.0, normal = 0.0;
    for (const auto& p : s) {
      worst = std::max(worst, std::abs(p.error()));
      mean += p.error() / s.size();
      drag += p.along;
      normal += p.normal;
    }
    double ripple = 0.0;
    for (const auto& p : s) ripple = std::max(ripple, std::abs(p.error() - mean));
    std::printf("edge %4.1f mm, refinement %s: normal force against the exact one: mean %+.2f%%, worst %.2f%%, "
                "ripple %.2f%% over %zu samples; sideways / normal %+.4f\n", c.edge * 1e3,
                haptics::to_string(c.refine), 100 * mean, 100 * worst, 100 * ripple, s.size(), drag / normal);
    EXPECT_GT(s.size(), 70u);
    if (c.refine == haptics::Refine::On) {
      EXPECT_LE(worst, 0.03) << c.edge;
      EXPECT_LE(ripple, c.edge < 20e-3 ? 0.01 : 0.02) << c.edge;
    } else {
      EXPECT_GT(ripple, 0.05) << "the unrefined mesh's facets, which the check must see";
    }
    EXPECT_LT(std::abs(drag / normal), 0.01) << c.edge;  // frictionless: no drag beyond 1%
  }
}
