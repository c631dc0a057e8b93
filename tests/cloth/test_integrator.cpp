// The alpha-implicit Euler of eqs. 8-9: convergence order, conservation, allocation-free
// stepping, and named, counted recovery from blow-ups.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <optional>
#include <vector>

#include "cloth/integrator.hpp"
#include "support/alloc_counter.hpp"
#include "support/fixtures.hpp"

using namespace hapticloth;
using cloth::Vec3;

namespace {

// A vertical 0.2 m sheet pinned along its top edge (plane xz, gravity -z), 6 x 6 quads.
cloth::ClothModel vertical_sheet(const cloth::Material& mat, int n = 6) {
  cloth::GridSpec g;
  g.width = g.height = 0.2;
  g.nx = g.ny = n;
  g.plane = cloth::GridPlane::XZ;
  g.origin = {-0.1, 0.0, -0.2};
  const auto mesh = cloth::make_grid(g);
  return cloth::build_model(mesh, mat, cloth::grid_edge(mesh, "top"));
}

// A drum: a 0.2 m square pinned on all four edges, pre-stretched by 5% so that every element is
// in tension, given a smooth out-of-plane velocity (the fundamental mode's shape). Tension keeps
// the motion well posed: a membrane without bending under compression buckles, and nearby
// trajectories of a buckling membrane diverge, which no time-step refinement can converge.
cloth::ClothModel drum(const cloth::Material& mat, int n = 8) {
  cloth::GridSpec g;
  g.width = g.height = 0.2;
  g.nx = g.ny = n;
  g.origin = {-0.1, -0.1, 0.0};
  const auto mesh = cloth::make_grid(g);
  std::vector<int> pins;
  for (const char* e : {"top", "bottom", "left", "right"})
    for (int v : cloth::grid_edge(mesh, e)) pins.push_back(v);
  return cloth::build_model(mesh, mat, pins);
}

cloth::ClothState smooth_start(const cloth::ClothModel& m) {
  cloth::ClothState s = cloth::rest_state(m);
  for (int i = 0; i < m.num_vertices(); ++i) {
    const Vec3 p = m.rest_positions[i];
    s.x[i] = 1.05 * p;
    if (m.pinned[i]) continue;
    s.v[i].z() = 0.5 * std::cos(M_PI * p.x() / 0.2) * std::cos(M_PI * p.y() / 0.2);
  }
  return s;
}

cloth::ClothState run(const cloth::ClothModel& m, double alpha, double dt, double T,
                      cloth::IntegratorEvents* ev = nullptr) {
  cloth::IntegratorConfig cfg;
  cfg.dt = dt;
  cfg.alpha = alpha;
  cfg.jacobian = cloth::JacobianMode::Exact;  // the order holds for the exact Jacobian
  cloth::Integrator integ(m, cfg, cloth::make_cholmod_solver());
  cloth::ClothState s = smooth_start(m);
  const long n = std::lround(T / dt);
  for (long k = 0; k < n; ++k) integ.step(s);
  if (ev) *ev = integ.events();
  return s;
}

double max_distance(const cloth::ClothState& a, const cloth::ClothState& b) {
  double e = 0.0;
  for (size_t i = 0; i < a.x.size(); ++i) e = std::max(e, (a.x[i] - b.x[i]).norm());
  return e;
}

}  // namespace

// Observed order of convergence against a fine-dt reference on a smooth motion: about 1 for
// alpha = 1 (backward Euler) and about 2 for alpha = 0.5 (linearized midpoint).
TEST(Integrator, ConvergenceOrder) {
  const auto m = drum(test::denim(0.0, 0.2));
  const double T = 0.1;
  for (double alpha : {1.0, 0.5}) {
    cloth::IntegratorEvents ev;
    const auto ref = run(m, alpha, 1e-3 / 64, T);
    std::vector<double> err;
    for (double dt : {1e-3, 5e-4, 2.5e-4}) {
      err.push_back(max_distance(run(m, alpha, dt, T, &ev), ref));
      EXPECT_EQ(ev.total(), 0u) << "no event expected on a smooth motion";
    }
    const double p1 = std::log2(err[0] / err[1]), p2 = std::log2(err[1] / err[2]);
    std::printf("alpha %.1f: errors %.3e %.3e %.3e m, observed order %.2f %.2f\n", alpha, err[0],
                err[1], err[2], p1, p2);
    if (alpha == 1.0) {
      EXPECT_NEAR(p2, 1.0, 0.25);
    } else {
      EXPECT_NEAR(p2, 2.0, 0.3);
    }
    EXPECT_GT(err[0], 1e-9) << "errors must be measurable, not round-off";
  }
}

// Without gravity or pins, internal forces conserve momentum exactly (up to the solve).
TEST(Integrator, ConservesMomentumOfFreeCloth) {
  cloth::GridSpec g;
  g.nx = g.ny = 8;
  g.width = g.height = 0.2;
  const auto mesh = cloth::make_grid(g);
  const auto m = cloth::build_model(mesh, test::denim(0.3), {});
  cloth::IntegratorConfig cfg;
  cfg.dt = 0.005;
  cfg.gravity.setZero();
  cloth::Integrator integ(m, cfg, cloth::make_cholmod_solver());
  cloth::ClothState s = cloth::rest_state(m);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(-1, 1);
  for (auto& v : s.v) v = Vec3(U(rng), U(rng), U(rng));
  auto momentum = [&]() {
    Vec3 p = Vec3::Zero();
    for (int i = 0; i < m.num_vertices(); ++i) p += m.mass[i] * s.v[i];
    return p;
  };
  const Vec3 p0 = momentum();
  for (int k = 0; k < 200; ++k) ASSERT_EQ(integ.step(s), cloth::StepOutcome::Accepted);
  EXPECT_LE((momentum() - p0).norm(), 1e-9 * p0.norm());
  // ... and it damps relative motion: the energy of the internal motion decreases.
  EXPECT_EQ(integ.events().total(), 0u);
}

TEST(Integrator, PinnedVerticesMoveOnlyWithTheirVelocity) {
  const auto m = vertical_sheet(test::denim());
  cloth::Integrator integ(m, {.dt = 0.002}, cloth::make_pcg_solver({}));
  cloth::ClothState s = cloth::rest_state(m);
  const Vec3 pull(0.0, 0.0, 0.01);  // m/s, upwards
  for (int i = 0; i < m.num_vertices(); ++i)
    if (m.pinned[i]) s.v[i] = pull;
  for (int k = 0; k < 100; ++k) integ.step(s);
  for (int i = 0; i < m.num_vertices(); ++i) {
    if (m.pinned[i]) {
      EXPECT_LE((s.x[i] - (m.rest_positions[i] + 0.2 * pull)).norm(), 1e-12);
    }
  }
  // the free vertices followed (the cloth hangs from the moving edge)
  double lowest = 1e9;
  for (const auto& x : s.x) lowest = std::min(lowest, x.z());
  EXPECT_GT(lowest, -0.21);
  EXPECT_LT(lowest, -0.19 + 0.002);
}

class StepAllocation : public ::testing::TestWithParam<const char*> {};

// After the first step, stepping allocates nothing on the heap, with either solver and with
// viscosity and air damping on.
TEST_P(StepAllocation, NoHeapAllocationAfterFirstStep) {
  const auto m = drum(test::denim(0.2), 10);
  cloth::IntegratorConfig cfg;
  cfg.dt = 0.002;
  cfg.air_damping = 0.5;
  cloth::PcgOptions po;
  po.tolerance = 1e-8;
  cloth::Integrator integ(m, cfg, cloth::make_solver(GetParam(), po));
  cloth::ClothState s = smooth_start(m);
  integ.step(s);
  test::AllocationGuard guard;
  for (int k = 0; k < 50; ++k) integ.step(s);
  const auto n = guard.count();
  EXPECT_EQ(n, 0u) << GetParam() << " allocated " << n << " times in 50 steps";
  EXPECT_GT(s.time, 0.1);
}
INSTANTIATE_TEST_SUITE_P(Solvers, StepAllocation, ::testing::Values("pcg", "cholmod"));

// The guard itself counts: a vector allocation is seen.
TEST(StepAllocationGuard, CountsAllocations) {
  test::AllocationGuard guard;
  void* volatile p = std::malloc(64);  // volatile: the call cannot be elided
  const auto n = guard.count();
  std::free(p);
  EXPECT_GE(n, 1u);
}

TEST(IntegratorRecovery, NanStateIsRestoredAndCounted) {
  const auto m = vertical_sheet(test::denim());
  cloth::IntegratorConfig cfg;
  cloth::Integrator integ(m, cfg, cloth::make_cholmod_solver());
  cloth::ClothState s = cloth::rest_state(m);
  for (int k = 0; k < 10; ++k) integ.step(s);
  s.x[20].x() = std::nan("");
  EXPECT_EQ(integ.step(s), cloth::StepOutcome::Restored);
  EXPECT_EQ(integ.events().non_finite, 1u);
  EXPECT_EQ(integ.events().restores, 1u);
  for (const auto& x : s.x) EXPECT_TRUE(x.allFinite());
  EXPECT_EQ(integ.step(s), cloth::StepOutcome::Accepted);
}

TEST(IntegratorRecovery, NanForceIsRejectedRetriedAndRestored) {
  const auto m = vertical_sheet(test::denim());
  cloth::Integrator integ(m, {.max_halvings = 2}, cloth::make_pcg_solver({}));
  cloth::ClothState s = cloth::rest_state(m);
  integ.external_forces()[30] = Vec3(0, std::nan(""), 0);
  EXPECT_EQ(integ.step(s), cloth::StepOutcome::Restored);
  // dt, then dt/2 (first half fails), then dt/4 (first quarter fails): 3 attempts, 2 retries
  EXPECT_EQ(integ.events().non_finite, 3u);
  EXPECT_EQ(integ.events().retries, 2u);
  EXPECT_EQ(integ.events().restores, 1u);
  for (const auto& x : s.x) EXPECT_TRUE(x.allFinite());
  integ.external_forces()[30].setZero();
  EXPECT_EQ(integ.step(s), cloth::StepOutcome::Accepted);
}

TEST(IntegratorRecovery, SolverFailureRetriesWithSmallerSteps) {
  // A PCG allowed too few iterations for dt fails, but converges on the halved step.
  const auto m = drum(test::denim(), 8);
  cloth::IntegratorConfig cfg;
  cfg.dt = 0.02;
  cloth::PcgOptions po;
  po.tolerance = 1e-6;
  po.max_iterations = 14;  // SSOR: 20 converge at dt (block-Jacobi needed more than 25)
  cloth::Integrator integ(m, cfg, cloth::make_pcg_solver(po));
  cloth::ClothState s = smooth_start(m);
  for (int k = 0; k < 20; ++k) integ.step(s);
  const auto& ev = integ.events();
  EXPECT_GT(ev.solver_not_converged, 0u);
  EXPECT_GT(ev.retries, 0u);
  for (const auto& x : s.x) EXPECT_TRUE(x.allFinite());
  EXPECT_NEAR(s.time, 0.4, 1e-12);
}

TEST(IntegratorRecovery, EnergyExplosionIsDetected) {
  // Pins yanked at 50 m/s pump energy into the cloth far faster than the explosion limit allows.
  const auto m = vertical_sheet(test::denim());
  cloth::IntegratorConfig cfg;
  cfg.dt = 0.001;
  cfg.max_halvings = 1;
  cfg.explosion_ratio = 0.01;
  cloth::Integrator integ(m, cfg, cloth::make_cholmod_solver());
  cloth::ClothState s = cloth::rest_state(m);
  for (int i = 0; i < m.num_vertices(); ++i)
    if (m.pinned[i]) s.v[i] = Vec3(0, 0, 50.0);
  for (int k = 0; k < 5; ++k) integ.step(s);
  EXPECT_GT(integ.events().energy_explosions, 0u);
  EXPECT_GT(integ.events().restores, 0u);
  for (const auto& x : s.x) EXPECT_TRUE(x.allFinite());
}

// A solver whose answer overshoots by a fixed factor: every step gains a fraction of the
// energy, too little for the per-step test, so only the summed excess can catch it.
class OvershootingSolver : public cloth::LinearSolver {
 public:
  explicit OvershootingSolver(double f) : inner_(cloth::make_cholmod_solver()), f_(f) {}
  const char* name() const override { return "overshooting"; }
  void analyze(const cloth::SymCsr& A) override { inner_->analyze(A); }
  cloth::SolveStatus solve(const cloth::SymCsr& A, const double* b, double* x) override {
    const auto st = inner_->solve(A, b, x);
    for (int i = 0; i < A.n; ++i) x[i] *= f_;
    return st;
  }

 private:
  std::unique_ptr<cloth::LinearSolver> inner_;
  double f_;
};

TEST(IntegratorRecovery, SlowBlowUpIsCaught) {
  const auto m = drum(test::denim(), 8);
  cloth::IntegratorConfig cfg;
  cfg.dt = 0.005;
  cfg.alpha = 0.5;
  cfg.max_halvings = 1;
  cloth::Integrator integ(m, cfg, std::make_unique<OvershootingSolver>(1.3));
  cloth::ClothState s = smooth_start(m);
  double max_ke = 0.0;
  for (int k = 0; k < 400; ++k) {
    integ.step(s);
    max_ke = std::max(max_ke, cloth::compute_energies(m, s, cfg.gravity).kinetic);
  }
  const auto& ev = integ.events();
  EXPECT_GT(ev.energy_explosions, 0u);
  EXPECT_GT(ev.restores, 0u);
  for (const auto& x : s.x) EXPECT_TRUE(x.allFinite());
  // the kinetic energy stays bounded (the explosion limit is 10x the energy floor, about 2 J
  // here); without the energy-balance check it reaches 1e72 J
  EXPECT_LT(max_ke, 5.0);
}

TEST(IntegratorConfig, RejectsBadSettings) {
  cloth::IntegratorConfig c;
  c.alpha = 0.3;
  EXPECT_THROW(c.validate(), std::invalid_argument);
  c = {};
  c.dt = 0.0;
  EXPECT_THROW(c.validate(), std::invalid_argument);
  c = {};
  c.air_damping = -1;
  EXPECT_THROW(c.validate(), std::invalid_argument);
  c = {};
  c.assembly_threads = 3;
  EXPECT_THROW(c.validate(), std::invalid_argument);
  for (double refresh : {-1e-4, 1.0, std::nan("")}) {
    c = {};
    c.matrix_refresh = refresh;
    EXPECT_THROW(c.validate(), std::invalid_argument) << refresh;
  }
}

// The integrator's fused element pass (forces, factored Jacobians, system blocks and
// right-hand side in one sweep) against eq. 9 assembled densely from evaluate_element's 3x3
// blocks, which the finite-difference tests check. Random deformed states, some vertices
// pinned, with and without viscosity, both Jacobian modes, and an external force; at every
// instruction level this CPU runs (the lanes' scatter and its transposes differ by level).
struct FusedAssembly
    : ::testing::TestWithParam<std::tuple<double, cloth::JacobianMode, cloth::SimdLevel>> {};

TEST_P(FusedAssembly, EqualsReferenceBuiltFromElementBlocks) {
  const auto [viscosity, mode, level] = GetParam();
  if (!cloth::runs_here(level)) GTEST_SKIP() << cloth::to_string(level) << ": this CPU lacks its instructions";
  const cloth::Material mat = test::denim(viscosity);
  const cloth::ClothModel m = vertical_sheet(mat, 5);
  cloth::IntegratorConfig cfg;
  cfg.simd = level;
  cfg.alpha = 0.7;
  cfg.air_damping = 0.3;
  cloth::Integrator integ(m, cfg, cloth::make_cholmod_solver());
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  const double h = 0.004;
  for (int trial = 0; trial < 5; ++trial) {
    cloth::ClothState s = cloth::rest_state(m);
    for (int i = 0; i < m.num_vertices(); ++i) {
      // up to 15% stretch or compression, out-of-plane noise and random velocities
      s.x[i] = Vec3(1.0 + 0.15 * U(rng), 1.0 + 0.15 * U(rng), 1.0).cwiseProduct(s.x[i]) +
               0.01 * Vec3(U(rng), U(rng), U(rng));
      s.v[i] = Vec3(U(rng), U(rng), U(rng));
    }
    for (auto& f : integ.external_forces()) f = Vec3(U(rng), U(rng), U(rng));
    const cloth::SymCsr& A = integ.system_matrix(s, h, mode);
    const Eigen::VectorXd& rhs = integ.system_rhs();

    const int n = 3 * m.num_free();
    Eigen::MatrixXd Aref = Eigen::MatrixXd::Zero(n, n);
    Eigen::VectorXd bref = Eigen::VectorXd::Zero(n);
    const double a = cfg.alpha;
    cloth::EvalRequest req;
    req.mode = mode;
    cloth::ElementEval ev;
    for (const auto& e : m.elements) {
      const Vec3* x[3] = {&s.x[e.v[0]], &s.x[e.v[1]], &s.x[e.v[2]]};
      const Vec3* v[3] = {&s.v[e.v[0]], &s.v[e.v[1]], &s.v[e.v[2]]};
      cloth::evaluate_element(e, mat, x, v, req, ev);
      for (int k = 0; k < 3; ++k) {
        const int fk = m.free_index[e.v[k]];
        if (fk < 0) continue;
        Vec3 Hv = Vec3::Zero();
        for (int l = 0; l < 3; ++l) {
          Hv += ev.H[k][l] * *v[l];
          const int fl = m.free_index[e.v[l]];
          if (fl < 0) continue;
          Aref.block<3, 3>(3 * fk, 3 * fl) += a * a * h * h * ev.H[k][l] + a * h * ev.C[k][l];
        }
        bref.segment<3>(3 * fk) += h * (ev.f[k] - a * h * Hv);
      }
    }
    for (int f = 0; f < m.num_free(); ++f) {
      const int i = m.free_vertices[f];
      const double c = cfg.air_damping * m.vertex_area[i];
      Aref.block<3, 3>(3 * f, 3 * f) += (m.mass[i] + a * h * c) * Eigen::Matrix3d::Identity();
      bref.segment<3>(3 * f) += h * (m.mass[i] * cfg.gravity - c * s.v[i] + integ.external_forces()[i]);
    }
    Eigen::MatrixXd Afused = Eigen::MatrixXd::Zero(n, n);
    for (int r = 0; r < n; ++r)
      for (int k = A.rowptr[r]; k < A.rowptr[r + 1]; ++k) Afused(r, A.col[k]) = A.val[k];
    ASSERT_GT(Aref.norm(), 0.0);
    EXPECT_LE((Afused - Aref).cwiseAbs().maxCoeff(), 1e-12 * Aref.cwiseAbs().maxCoeff())
        << "trial " << trial;
    EXPECT_LE((rhs - bref).cwiseAbs().maxCoeff(), 1e-12 * bref.cwiseAbs().maxCoeff())
        << "trial " << trial;
  }
}

INSTANTIATE_TEST_SUITE_P(
    ViscosityModeAndLevel, FusedAssembly,
    ::testing::Combine(::testing::Values(0.0, 0.05),
                       ::testing::Values(cloth::JacobianMode::Spd, cloth::JacobianMode::Exact),
                       ::testing::Values(cloth::SimdLevel::Baseline, cloth::SimdLevel::Avx2,
                                         cloth::SimdLevel::Avx512)));

// Two-thread assembly (assembly_threads 2: element parts on the helper and the caller, then the
// separators) gives the one-thread system to rounding, and steps without allocating. A 40 x 40
// drum (3200 elements: above kMinParallelElements) in a random deformed state.
TEST(Integrator, TwoThreadAssemblyEqualsOneThread) {
  const auto m = drum(test::denim(0.05), 40);
  ASSERT_GE(m.num_triangles(), cloth::kMinParallelElements);
  cloth::IntegratorConfig one, two;
  one.proxies = two.proxies = 2;  // their rows are cleared with the rest (Integrator::plan_clearing)
  two.assembly_threads = 2;
  cloth::Integrator a(m, one, cloth::make_cholmod_solver()), b(m, two, cloth::make_cholmod_solver());
  for (auto* integ : {&a, &b})
    for (auto& p : integ->proxies()) p.stiffness = 800.0;  // something in their rows to clear
  cloth::ClothState s = smooth_start(m);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  for (int i = 0; i < m.num_vertices(); ++i) s.x[i] += 0.002 * Vec3(U(rng), U(rng), U(rng));
  const cloth::SymCsr A1 = a.system_matrix(s, 0.002, cloth::JacobianMode::Spd);
  const Eigen::VectorXd b1 = a.system_rhs();
  // Assembled twice: each part's thread clears its own rows, so every row must start from 0.
  b.system_matrix(smooth_start(m), 0.002, cloth::JacobianMode::Spd);
  const cloth::SymCsr& A2 = b.system_matrix(s, 0.002, cloth::JacobianMode::Spd);
  double amax = 0.0, adiff = 0.0;
  for (size_t k = 0; k < A1.val.size(); ++k) {
    amax = std::max(amax, std::abs(A1.val[k]));
    adiff = std::max(adiff, std::abs(A1.val[k] - A2.val[k]));
  }
  EXPECT_LE(adiff, 1e-13 * amax);
  EXPECT_LE((b1 - b.system_rhs()).cwiseAbs().maxCoeff(), 1e-13 * b1.cwiseAbs().maxCoeff());
  cloth::ClothState sa = s, sb = s;
  a.step(sa);
  b.step(sb);
  EXPECT_LE(max_distance(sa, sb), 1e-12);
  test::AllocationGuard guard;
  for (int k = 0; k < 5; ++k) b.step(sb);
  EXPECT_EQ(guard.count(), 0u);
}

// Every assembly starts from zero, the proxies' rows too (a proxy's row has a block for every
// free node; springs write the blocks of their corners): a matrix assembled with springs under
// one spot of the drum and then with springs under another is, to the bit, the matrix a fresh
// integrator assembles with the second set alone, on one thread and on two.
TEST(Integrator, ProxyRowsHoldOnlyTheCurrentSprings) {
  const auto m = drum(test::denim(), 40);
  const cloth::ClothState s = smooth_start(m);
  auto springs_at = [&](const Vec3& spot) {
    std::vector<cloth::PointSpring> out;
    for (int t = 0; t < m.num_triangles(); ++t) {
      if ((m.rest_positions[m.elements[t].v[0]] - spot).norm() > 0.02) continue;
      for (int f = 0; f < 2; ++f) {
        cloth::PointSpring sp;
        sp.tri = t;
        sp.b[0] = 0.2;
        sp.b[1] = 0.3;
        sp.b[2] = 0.5;
        sp.proxy = f;
        sp.f = Vec3(0.0, 0.0, f ? -0.05 : 0.05);
        sp.K = 2000.0 * cloth::Mat3::Identity();
        out.push_back(sp);
      }
    }
    return out;
  };
  const Vec3 centre = m.rest_positions[m.num_vertices() / 2];
  const auto first = springs_at(centre + Vec3(-0.05, 0.0, 0.0)), second = springs_at(centre + Vec3(0.05, 0.0, 0.0));
  ASSERT_FALSE(first.empty());
  ASSERT_FALSE(second.empty());
  for (int threads : {1, 2}) {
    cloth::IntegratorConfig cfg;
    cfg.proxies = 2;
    cfg.assembly_threads = threads;
    cloth::Integrator reused(m, cfg, cloth::make_cholmod_solver()), fresh(m, cfg, cloth::make_cholmod_solver());
    reused.point_springs() = first;
    reused.system_matrix(s, 0.001, cloth::JacobianMode::Spd);
    reused.point_springs() = second;
    fresh.point_springs() = second;
    const cloth::SymCsr& A1 = reused.system_matrix(s, 0.001, cloth::JacobianMode::Spd);
    const cloth::SymCsr& A2 = fresh.system_matrix(s, 0.001, cloth::JacobianMode::Spd);
    double amax = 0.0, adiff = 0.0;
    for (size_t k = 0; k < A1.val.size(); ++k) {
      amax = std::max(amax, std::abs(A2.val[k]));
      adiff = std::max(adiff, std::abs(A1.val[k] - A2.val[k]));
    }
    EXPECT_EQ(adiff, 0.0) << threads << " thread(s), largest entry " << amax;
  }
}

// The proxies' response (the multirate path's local model) is the derivative of the step's
// solution with respect to the targets: two fingertips pinch a drum through stiff point
// springs; moving one target by 0.1 mm and stepping again from the same state moves the proxies
// by R alpha h k / (alpha h k + c) times that, the other proxy too (through the cloth), to the
// direct solver's precision.
TEST(Integrator, ProxyResponseIsTheStepsDerivativeInTheTargets) {
  const auto m = drum(test::denim(), 8);
  cloth::IntegratorConfig cfg;
  cfg.dt = 0.02;
  cfg.proxies = 2;
  cfg.gravity.setZero();
  const cloth::ClothState s0 = cloth::rest_state(m);
  const Vec3 centre = m.rest_positions[m.num_vertices() / 2];
  const Vec3 n = Vec3::UnitZ();
  auto step_with = [&](const Vec3& dt0, std::vector<cloth::Mat3>* M) {
    cloth::Integrator integ(m, cfg, cloth::make_cholmod_solver());
    for (int f = 0; f < 2; ++f) {
      auto& p = integ.proxies()[f];
      p.x = centre + (f ? -0.008 : 0.008) * n;
      p.target = p.x + (f ? 0.002 : -0.002) * n + (f ? Vec3::Zero() : dt0);
      p.stiffness = 800.0;
      p.damping = 1.0;
    }
    for (int t = 0; t < m.num_triangles(); ++t) {
      const auto& e = m.elements[t];
      if ((m.rest_positions[e.v[0]] - centre).norm() > 0.06) continue;
      for (int f = 0; f < 2; ++f) {
        cloth::PointSpring sp;
        sp.tri = t;
        sp.b[0] = sp.b[1] = sp.b[2] = 1.0 / 3.0;
        sp.proxy = f;
        sp.f = (f ? -0.05 : 0.05) * n;
        sp.K = 2000.0 * n * n.transpose() + 500.0 * (cloth::Mat3::Identity() - n * n.transpose());
        integ.point_springs().push_back(sp);
      }
    }
    cloth::ClothState s = s0;
    EXPECT_EQ(integ.step(s), cloth::StepOutcome::Accepted);
    if (M) {
      EXPECT_TRUE(integ.proxy_response(*M));
    }
    return std::array<Vec3, 2>{integ.proxies()[0].x, integ.proxies()[1].x};
  };
  std::vector<cloth::Mat3> R;
  const auto base = step_with(Vec3::Zero(), &R);
  ASSERT_EQ(R.size(), 4u);
  const double ahk = cfg.dt * 800.0;
  std::vector<cloth::Mat3> M;  // dx_p / dT_q
  for (const auto& r : R) M.push_back(r * ahk / (ahk + 1.0));
  for (int c = 0; c < 3; ++c) {
    const double d = 1e-4;
    const auto moved = step_with(d * Vec3::Unit(c), nullptr);
    for (int p = 0; p < 2; ++p) {
      const Vec3 fd = (moved[p] - base[p]) / d;
      EXPECT_LE((fd - M[p * 2 + 0].col(c)).norm(), 1e-6 * (1.0 + M[p * 2 + 0].col(c).norm()))
          << "proxy " << p << ", target 0 axis " << c << ": " << fd.transpose() << " vs "
          << M[p * 2 + 0].col(c).transpose();
    }
  }
  // Pushing finger 0 into the drum moves finger 1 (on the other side) along: the cloth couples them.
  EXPECT_GT(M[1 * 2 + 0](2, 2), 0.05);
}

namespace {

// A drum pre-stretched at rest sags under gravity while two proxies push on it through point
// springs, the springs' set moved between two spots every third step: small, smooth motion with
// spring terms that come and go, a kept matrix's case. `check(before, after, integ, springs)`
// runs after each step.
template <class Check>
void pinched_drum(int threads, double refresh, const cloth::PcgOptions& pcg, int steps, Check check,
                  std::optional<cloth::SimdLevel> level = std::nullopt) {
  const auto m = drum(test::denim(0.05), 40);
  cloth::IntegratorConfig cfg;
  cfg.simd = level;
  cfg.proxies = 2;
  cfg.assembly_threads = threads;
  cfg.matrix_refresh = refresh;
  cloth::Integrator integ(m, cfg, cloth::make_pcg_solver(pcg));
  const Vec3 centre = m.rest_positions[m.num_vertices() / 2];
  std::vector<cloth::PointSpring> sets[2];
  for (int t = 0; t < m.num_triangles(); ++t)
    for (int k = 0; k < 2; ++k) {
      const Vec3 spot = centre + Vec3(k ? 0.03 : -0.03, 0.0, 0.0);
      if ((m.rest_positions[m.elements[t].v[0]] - spot).norm() > 0.012) continue;
      cloth::PointSpring sp;
      sp.tri = t;
      sp.b[0] = 0.2;
      sp.b[1] = 0.3;
      sp.b[2] = 0.5;
      sp.proxy = t % 2;
      sp.f = Vec3(0.0, 0.0, -0.02);
      sp.K = 300.0 * cloth::Mat3::Identity();
      sets[k].push_back(sp);
    }
  ASSERT_FALSE(sets[0].empty());
  ASSERT_FALSE(sets[1].empty());
  for (int j = 0; j < 2; ++j) {
    integ.proxies()[j].stiffness = 400.0;
    integ.proxies()[j].damping = 0.5;
    integ.proxies()[j].x = integ.proxies()[j].target = centre;
  }
  cloth::ClothState s = cloth::rest_state(m);
  for (int i = 0; i < m.num_vertices(); ++i) s.x[i] = 1.05 * m.rest_positions[i];
  for (int k = 0; k < steps; ++k) {
    integ.point_springs() = sets[k / 3 % 2];
    const cloth::ClothState before = s;
    integ.step(s);
    check(before, s, integ, sets[k / 3 % 2]);
  }
}

double largest(const std::vector<double>& v) {
  double a = 0.0;
  for (double x : v) a = std::max(a, std::abs(x));
  return a;
}

}  // namespace

// A kept matrix (IntegratorConfig::matrix_refresh) is the matrix formed whole at the step's
// start, with the step's springs and none of the last step's, but for the elements that moved
// less than the tolerance since their blocks were formed: within it (1e-3) of the largest
// entry, and to rounding at a tolerance of 1e-12. On one thread and on two, and most steps kept.
TEST(Integrator, AKeptMatrixIsTheMatrixFormedWholeWithinItsTolerance) {
  cloth::PcgOptions pcg;
  pcg.tolerance = 1e-8;
  for (int threads : {1, 2})
    for (double refresh : {1e-3, 1e-12}) {
      int kept = 0, refreshed_some = 0, steps = 0;
      double worst = 0.0;
      pinched_drum(threads, refresh, pcg, 30, [&](const cloth::ClothState& before, const cloth::ClothState&,
                                                  cloth::Integrator& integ,
                                                  const std::vector<cloth::PointSpring>& springs) {
        const std::vector<double> held = integ.matrix().val;
        cloth::IntegratorConfig cfg = integ.config();
        cfg.matrix_refresh = 0.0;
        cloth::Integrator whole(integ.model(), cfg, cloth::make_cholmod_solver());
        whole.proxies() = integ.proxies();
        whole.point_springs() = springs;
        const cloth::SymCsr& A = whole.system_matrix(before, cfg.dt, cloth::JacobianMode::Spd);
        double diff = 0.0;
        for (size_t k = 0; k < held.size(); ++k) diff = std::max(diff, std::abs(held[k] - A.val[k]));
        worst = std::max(worst, diff / largest(A.val));
        ++steps;
        kept += integ.last_timing().whole_assemblies == 0;
        refreshed_some += integ.last_timing().refreshed_elements < integ.model().num_triangles();
      });
      EXPECT_LE(worst, refresh == 1e-3 ? 2e-3 : 1e-12) << threads << " thread(s), refresh " << refresh;
      EXPECT_GE(kept, steps - 1) << threads << " thread(s), refresh " << refresh;
      if (refresh == 1e-3) EXPECT_GE(refreshed_some, steps / 2) << threads << " thread(s)";
    }
}

// The element pass is the only code that differs by instruction level, and its units compute
// the same IEEE operations at every width (no FMA contraction): the pinched drum (two proxies
// on springs, viscosity, a kept matrix, two threads) steps to the same cloth and the same proxy
// displacements, the force a fingertip renders, to the last bit at every level this CPU runs.
TEST(Integrator, EveryInstructionLevelStepsTheSameCloth) {
  std::vector<std::vector<double>> runs;
  for (cloth::SimdLevel level : cloth::levels_here()) {
    std::vector<double> trace;
    pinched_drum(2, 1e-3, {}, 30, [&](const cloth::ClothState&, const cloth::ClothState& after,
                                      cloth::Integrator& integ, const std::vector<cloth::PointSpring>&) {
      EXPECT_EQ(integ.simd_level(), level);
      for (const auto& p : integ.proxies())
        for (int c = 0; c < 3; ++c) trace.push_back(p.displacement[c]);
      for (const Vec3& x : after.x)
        for (int c = 0; c < 3; ++c) trace.push_back(x[c]);
    }, level);
    runs.push_back(trace);
  }
  std::printf("levels here: %zu\n", runs.size());
  for (std::size_t l = 1; l < runs.size(); ++l) {
    ASSERT_EQ(runs[l].size(), runs[0].size());
    std::size_t differ = 0;
    for (std::size_t i = 0; i < runs[0].size(); ++i) differ += runs[l][i] != runs[0][i];
    EXPECT_EQ(differ, 0u) << cloth::to_string(cloth::levels_here()[l]) << " against baseline";
  }
}

// What the solver solves is the kept matrix: the rows its changes reach are reloaded into the
// PCG's copy (LinearSolver::solve_changed), so each step's dv leaves a residual against the
// kept matrix at the PCG's tolerance (1e-10, double copy). Reloads of a few rows happen.
TEST(Integrator, TheSolverSolvesTheKeptMatrix) {
  cloth::PcgOptions pcg;
  pcg.tolerance = 1e-10;
  for (int threads : {1, 2}) {
    int reloads = 0;
    double worst = 0.0;
    pinched_drum(threads, 1e-3, pcg, 30, [&](const cloth::ClothState& before, const cloth::ClothState& after,
                                             cloth::Integrator& integ, const std::vector<cloth::PointSpring>&) {
      const cloth::ClothModel& m = integ.model();
      const cloth::SymCsr& A = integ.matrix();
      Eigen::VectorXd dv = Eigen::VectorXd::Zero(A.n), r(A.n);
      for (int i = 0; i < m.num_vertices(); ++i)  // eq. 9: v_new = v + dv
        if (m.free_index[i] >= 0) dv.segment<3>(3 * m.free_index[i]) = after.v[i] - before.v[i];
      const int nf = m.num_free();
      for (int j = 0; j < 2; ++j)
        dv.segment<3>(3 * (nf + j)) = integ.proxies()[j].displacement / (integ.config().alpha * integ.config().dt);
      A.multiply(dv.data(), r.data());
      r = integ.system_rhs() - r;
      worst = std::max(worst, r.norm() / integ.system_rhs().norm());
      const int rows = integ.last_timing().changed_rows;
      reloads += rows > 0 && rows < A.n / 12;
    });
    EXPECT_LE(worst, 1e-9) << threads << " thread(s)";
    EXPECT_GE(reloads, 10) << threads << " thread(s)";
  }
}

// A cloth hanging at rest has a right-hand side far below its weight's impulse over the step,
// and each step is solved to the solver's tolerance of the larger of the two
// (Integrator::weight_impulse, LinearSolver::set_residual_scale): the residual of every step
// stays within tolerance x h |g| |m|, and on some steps it is more than tolerance x |b|, which
// a solve relative to |b| alone would have gone on to.
TEST(Integrator, AClothAtRestIsSolvedToItsWeightsScale) {
  const auto m = vertical_sheet(test::denim(), 20);
  cloth::ClothState s = cloth::rest_state(m);
  {
    cloth::IntegratorConfig pre;
    pre.dt = 0.01;
    cloth::Integrator settle(m, pre, cloth::make_cholmod_solver());
    for (int k = 0; k < 300; ++k) settle.step(s);
    for (auto& v : s.v) v.setZero();
  }
  cloth::IntegratorConfig cfg;
  cfg.dt = 1e-3;
  const double tol = 1e-3;
  cloth::Integrator integ(m, cfg, cloth::make_pcg_solver({.tolerance = tol, .single_precision_matrix = true}));
  double m2 = 0.0;
  for (int v : m.free_vertices) m2 += m.mass[v] * m.mass[v];
  const double scale = cfg.dt * 9.81 * std::sqrt(m2);
  int floor_bound = 0, steps = 0;
  double worst = 0.0, smallest_b = 1e300;
  for (int k = 0; k < 100; ++k) {
    const cloth::ClothState before = s;
    integ.step(s);
    ASSERT_EQ(integ.last_timing().substeps, 1);
    EXPECT_NEAR(integ.solver().residual_scale(), scale, 1e-12 * scale);
    const cloth::SymCsr& A = integ.matrix();
    Eigen::VectorXd dv = Eigen::VectorXd::Zero(A.n), r(A.n);
    for (int i = 0; i < m.num_vertices(); ++i)  // eq. 9 at alpha 1: v_new = v + dv
      if (m.free_index[i] >= 0) dv.segment<3>(3 * m.free_index[i]) = s.v[i] - before.v[i];
    A.multiply(dv.data(), r.data());
    r = integ.system_rhs() - r;
    const double bn = integ.system_rhs().norm();
    smallest_b = std::min(smallest_b, bn / scale);
    worst = std::max(worst, r.norm() / (tol * std::max(bn, scale)));
    floor_bound += r.norm() > tol * bn;
    ++steps;
  }
  EXPECT_LT(smallest_b, 0.1) << "the cloth is not at rest";
  EXPECT_LE(worst, 1.05);  // the float copy's rounding on top of the tolerance
  EXPECT_GE(floor_bound, steps / 10) << "the solves went on to tolerance x |b|";
}
