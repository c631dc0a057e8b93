// Linear solvers: CHOLMOD and PCG agree; the system matrix of eq. 9 stays SPD on random states.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <memory>
#include <numeric>
#include <random>

#include "cloth/integrator.hpp"
#include "cloth/worker_pool.hpp"
#include "support/fixtures.hpp"

using namespace hapticloth;
using cloth::Vec3;

namespace {

struct Sheet {
  cloth::ClothModel model;
  explicit Sheet(int n = 12, double scale = 1.0) {
    cloth::GridSpec g;
    g.nx = g.ny = n;
    g.width = g.height = 0.3;
    const auto mesh = cloth::make_grid(g);
    model = cloth::build_model(mesh, test::denim(0.2, scale), cloth::grid_edge(mesh, "top"));
  }
};

// A random state: compressed, stretched, sheared and crumpled regions.
cloth::ClothState random_state(const cloth::ClothModel& m, std::mt19937& rng, double amp) {
  std::uniform_real_distribution<double> U(-1, 1);
  cloth::ClothState s = cloth::rest_state(m);
  const double a = U(rng), b = U(rng);
  for (int i = 0; i < m.num_vertices(); ++i) {
    if (m.pinned[i]) continue;
    const Vec3 p = m.rest_positions[i];
    // smooth large deformation (compression and shear) plus per-vertex noise
    s.x[i] = Vec3(p.x() * (1 + 0.3 * a) + 0.2 * b * p.y(), p.y() * (1 - 0.25 * a), 0.1 * std::sin(20 * p.x())) +
             amp * Vec3(U(rng), U(rng), U(rng));
    s.v[i] = Vec3(U(rng), U(rng), U(rng));
  }
  return s;
}

// The sheet with two fingertip proxies (800 N/m, 1 N s/m) at a random state: the system of a
// pinch once point springs are added (CHOLMOD is the integrator's own solver here).
struct PinchedSheet {
  Sheet sheet;
  cloth::ClothState s;
  cloth::IntegratorConfig cfg;
  std::unique_ptr<cloth::Integrator> integ;
  explicit PinchedSheet(std::mt19937& rng) : s(random_state(sheet.model, rng, 0.002)) {
    cfg.dt = 1e-3;
    cfg.proxies = 2;
    integ = std::make_unique<cloth::Integrator>(sheet.model, cfg, cloth::make_cholmod_solver());
    for (int f = 0; f < 2; ++f) {
      integ->proxies()[f].stiffness = 800.0;
      integ->proxies()[f].damping = 1.0;
    }
  }
  cloth::SymCsr system_matrix() { return integ->system_matrix(s, cfg.dt, cloth::JacobianMode::Spd); }
};

// `per_tri` stiff point springs (3 kN/m) at the centre of each triangle, to the two proxies in turn.
std::vector<cloth::PointSpring> centre_springs(std::initializer_list<int> tris, int per_tri) {
  std::vector<cloth::PointSpring> out;
  for (int tri : tris)
    for (int q = 0; q < per_tri; ++q) {
      cloth::PointSpring sp;
      sp.tri = tri;
      sp.b[0] = sp.b[1] = sp.b[2] = 1.0 / 3.0;
      sp.proxy = q % 2;
      sp.K = 3e3 * cloth::Mat3::Identity();
      out.push_back(sp);
    }
  return out;
}
void press_triangles(PinchedSheet& p, std::initializer_list<int> tris) {
  for (const auto& sp : centre_springs(tris, 6)) p.integ->point_springs().push_back(sp);
}

// The system of eq. 9 (Spd) of a step h from a random state of the sheet, a random right-hand
// side, and CHOLMOD's solution of it: what PCG is checked against.
struct Reference {
  cloth::SymCsr A;
  std::vector<double> b, x;
};

// A random right-hand side for A and CHOLMOD's solution.
Reference cholmod_reference(cloth::SymCsr A, std::mt19937& rng) {
  Reference ref{std::move(A), {}, {}};
  ref.b.resize(ref.A.n);
  for (auto& v : ref.b) v = std::uniform_real_distribution<double>(-1, 1)(rng);
  ref.x.assign(ref.A.n, 0.0);
  auto chol = cloth::make_cholmod_solver();
  chol->analyze(ref.A);
  EXPECT_EQ(chol->solve(ref.A, ref.b.data(), ref.x.data()), cloth::SolveStatus::Ok);
  return ref;
}

Reference cholmod_reference(const Sheet& sheet, std::mt19937& rng, double h) {
  const auto s = random_state(sheet.model, rng, 0.005);
  cloth::Integrator integ(sheet.model, cloth::IntegratorConfig{}, cloth::make_cholmod_solver());
  return cholmod_reference(integ.system_matrix(s, h, cloth::JacobianMode::Spd), rng);
}

constexpr cloth::PcgPreconditioner kPreconditioners[] = {cloth::PcgPreconditioner::BlockJacobi,
                                                        cloth::PcgPreconditioner::Ssor};

// |b - A x| / |b| with the double matrix.
double relative_residual(const cloth::SymCsr& A, const std::vector<double>& b, const std::vector<double>& x) {
  std::vector<double> r(A.n);
  A.multiply(x.data(), r.data());
  double res = 0, bn = 0;
  for (int i = 0; i < A.n; ++i) {
    res += (r[i] - b[i]) * (r[i] - b[i]);
    bn += b[i] * b[i];
  }
  return std::sqrt(res / bn);
}

double max_abs(const std::vector<double>& x) {
  double m = 0.0;
  for (double v : x) m = std::max(m, std::abs(v));
  return m;
}

// A PCG solve of A x = b from x = 0 with `po`: the solver (for its counters) and x; the
// status, which must be Ok, into `st`.
struct PcgRun {
  std::unique_ptr<cloth::LinearSolver> pcg;
  std::vector<double> x;
  cloth::SolveStatus st;
};
PcgRun pcg_solve(const cloth::SymCsr& A, const std::vector<double>& b, const cloth::PcgOptions& po) {
  PcgRun run{cloth::make_pcg_solver(po), std::vector<double>(A.n, 0.0), cloth::SolveStatus::Ok};
  run.pcg->analyze(A);
  run.st = run.pcg->solve(A, b.data(), run.x.data());
  return run;
}

double max_abs_diff(const std::vector<double>& x, const std::vector<double>& y) {
  double m = 0.0;
  for (size_t i = 0; i < x.size(); ++i) m = std::max(m, std::abs(x[i] - y[i]));
  return m;
}

}  // namespace

TEST(Solver, SystemMatrixIsSpdOnRandomStates) {
  Sheet sheet;
  std::mt19937 rng(11);
  int exact_not_spd = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const auto s = random_state(sheet.model, rng, 0.01);
    const double h = trial % 2 ? 0.04 : 0.005;
    for (auto mode : {cloth::JacobianMode::Spd, cloth::JacobianMode::Exact}) {
      cloth::IntegratorConfig cfg;
      cfg.dt = h;
      cfg.jacobian = mode;
      cloth::Integrator integ(sheet.model, cfg, cloth::make_cholmod_solver());
      const cloth::SymCsr& A = integ.system_matrix(s, h, mode);
      // Cholesky must succeed in Spd mode.
      auto chol = cloth::make_cholmod_solver();
      chol->analyze(A);
      std::vector<double> b(A.n, 1.0), x(A.n, 0.0);
      const auto st = chol->solve(A, b.data(), x.data());
      if (mode == cloth::JacobianMode::Spd) {
        EXPECT_EQ(st, cloth::SolveStatus::Ok) << "trial " << trial;
      } else if (st == cloth::SolveStatus::NotPositiveDefinite) {
        ++exact_not_spd;
      }
      // Symmetric values.
      for (int r = 0; r < A.n; ++r)
        for (int k = A.rowptr[r]; k < A.rowptr[r + 1]; ++k)
          ASSERT_NEAR(A.val[k], A.val[A.find(A.col[k], r)], 1e-9 * std::abs(A.val[k]) + 1e-15);
    }
  }
  // Without the Spd treatment, large steps on compressed states give indefinite systems.
  EXPECT_GT(exact_not_spd, 0);
}

TEST(Solver, PcgMatchesCholmod) {
  Sheet sheet;
  std::mt19937 rng(5);
  const auto [A, b, x1] = cholmod_reference(sheet, rng, 0.01);
  // CHOLMOD's residual is at round-off level.
  EXPECT_LE(relative_residual(A, b, x1), 1e-10);
  for (auto pre : kPreconditioners) {
    SCOPED_TRACE(cloth::to_string(pre));
    std::vector<double> x2(A.n, 0.0);
    auto pcg = cloth::make_pcg_solver({.tolerance = 1e-10, .preconditioner = pre});
    pcg->analyze(A);
    ASSERT_EQ(pcg->solve(A, b.data(), x2.data()), cloth::SolveStatus::Ok);
    EXPECT_GT(pcg->iterations(), 1);
    EXPECT_LE(max_abs_diff(x1, x2), 1e-8 * max_abs(x1));
    // The residual it reports is the true one, and meets the tolerance.
    EXPECT_LE(pcg->residual(), 1e-10);
    EXPECT_NEAR(relative_residual(A, b, x2), pcg->residual(), 1e-12);
    // Warm start from the solution converges at once.
    const int cold = pcg->iterations();
    ASSERT_EQ(pcg->solve(A, b.data(), x2.data()), cloth::SolveStatus::Ok);
    EXPECT_LT(pcg->iterations(), cold);
    // resolve(): the same matrix copy and preconditioner, another right-hand side.
    std::vector<double> b2(b.rbegin(), b.rend()), x3(A.n, 0.0), x3_chol(A.n, 0.0);
    auto chol = cloth::make_cholmod_solver();
    chol->analyze(A);
    ASSERT_EQ(chol->solve(A, b2.data(), x3_chol.data()), cloth::SolveStatus::Ok);
    ASSERT_EQ(pcg->resolve(A, b2.data(), x3.data()), cloth::SolveStatus::Ok);
    EXPECT_LE(max_abs_diff(x3, x3_chol), 1e-8 * max_abs(x3_chol));
  }
}

// The residual scale (LinearSolver::set_residual_scale): a right-hand side far below the scale
// is solved to tolerance x scale, not to tolerance x |b|; one above it as before. Both
// preconditioners, from a zero guess.
TEST(Solver, PcgStopsAtTheResidualScale) {
  Sheet sheet;
  std::mt19937 rng(5);
  const auto [A, b, x_chol] = cholmod_reference(sheet, rng, 0.01);
  double bn = 0.0;
  for (double v : b) bn += v * v;
  bn = std::sqrt(bn);
  std::vector<double> tiny(b);
  for (double& v : tiny) v *= 1e-3;
  const double tol = 1e-3;
  for (auto pre : kPreconditioners) {
    SCOPED_TRACE(cloth::to_string(pre));
    auto pcg = cloth::make_pcg_solver({.tolerance = tol, .preconditioner = pre});
    pcg->analyze(A);
    auto solve = [&](const std::vector<double>& rhs, double scale, std::vector<double>& x) {
      pcg->set_residual_scale(scale);
      x.assign(A.n, 0.0);
      EXPECT_EQ(pcg->solve(A, rhs.data(), x.data()), cloth::SolveStatus::Ok);
      return pcg->iterations();
    };
    std::vector<double> x;
    const int relative = solve(tiny, 0.0, x);
    EXPECT_LE(relative_residual(A, tiny, x), tol);
    // The scale of the full right-hand side: the tiny one needs only |r| <= tol |b|, 1000x its own.
    const int scaled = solve(tiny, bn, x);
    EXPECT_EQ(pcg->residual_scale(), bn);
    EXPECT_LE(relative_residual(A, tiny, x) * 1e-3 * bn, tol * bn * (1 + 1e-9));
    EXPECT_GT(relative_residual(A, tiny, x), tol) << "solved as far as without the scale";
    EXPECT_LT(scaled, relative);
    // A scale below |b| changes nothing.
    std::vector<double> x_full, x_low;
    const int full = solve(b, 0.0, x_full);
    EXPECT_EQ(solve(b, 1e-3 * bn, x_low), full);
    EXPECT_EQ(x_full, x_low);
  }
}

// SSOR against block-Jacobi on the step of a finer sheet at the scenes' tolerance: the same
// answer (within the tolerance times the step's condition), in fewer iterations: the sweeps
// carry a correction across the sheet in one iteration where block-Jacobi moves it one vertex.
TEST(Solver, SsorConvergesInFewerIterationsThanBlockJacobi) {
  Sheet sheet(40);
  std::mt19937 rng(12);
  const auto [A, b, x_chol] = cholmod_reference(sheet, rng, 0.002);
  int iterations[2];
  for (auto pre : kPreconditioners) {
    SCOPED_TRACE(cloth::to_string(pre));
    const auto [pcg, x, st] = pcg_solve(A, b, {.tolerance = 1e-3, .single_precision_matrix = true, .preconditioner = pre});
    ASSERT_EQ(st, cloth::SolveStatus::Ok);
    EXPECT_EQ(pcg->precision_fallbacks(), 0);  // the float copy solved it
    EXPECT_LE(relative_residual(A, b, x), 1.01e-3);
    EXPECT_LE(max_abs_diff(x, x_chol), 0.05 * max_abs(x_chol));
    iterations[pre == cloth::PcgPreconditioner::Ssor] = pcg->iterations();
  }
  EXPECT_LT(iterations[1], 0.6 * iterations[0]) << "SSOR " << iterations[1] << ", block-Jacobi " << iterations[0];
  // Over-relaxed, a free sheet converges in fewer still (docs/performance.md).
  const auto [relaxed, x, st] = pcg_solve(A, b, {.tolerance = 1e-3, .single_precision_matrix = true, .ssor_omega = 1.4});
  ASSERT_EQ(st, cloth::SolveStatus::Ok);
  EXPECT_EQ(relaxed->precision_fallbacks(), 0);
  EXPECT_LE(relative_residual(A, b, x), 1.01e-3);
  EXPECT_LT(relaxed->iterations(), iterations[1]) << "omega 1.4: " << relaxed->iterations() << ", 1: " << iterations[1];
}

// Two proxies (the fingertips) pinch a patch of the sheet through stiff point springs: the
// system has two dense hub rows of which a few blocks are non-zero. PCG leaves the zero blocks
// out and preconditions the hubs with the vertices they touch as one dense block: the answer
// is CHOLMOD's, in fewer iterations than with block-Jacobi alone.
TEST(Solver, PcgWithContactHubsMatchesCholmod) {
  std::mt19937 rng(8);
  PinchedSheet p(rng);
  const Vec3 n(0.0, 0.0, 1.0);
  const cloth::Mat3 K = 3e3 * n * n.transpose() + 3e3 * (cloth::Mat3::Identity() - n * n.transpose());
  std::uniform_real_distribution<double> U(0.05, 0.9);
  for (int tri : {100, 101, 102, 125}) {
    for (int q = 0; q < 10; ++q) {
      cloth::PointSpring sp;
      sp.tri = tri;
      sp.b[1] = U(rng) * 0.5;
      sp.b[2] = U(rng) * 0.5;
      sp.b[0] = 1.0 - sp.b[1] - sp.b[2];
      sp.proxy = q % 2;
      sp.f = 0.01 * (sp.proxy ? -n : n);
      sp.K = K;
      p.integ->point_springs().push_back(sp);
    }
  }
  const Reference ref = cholmod_reference(p.system_matrix(), rng);
  const cloth::SymCsr& A = ref.A;
  const std::vector<double>& b = ref.b;
  const std::vector<double>& x_chol = ref.x;
  const double nrm = max_abs(x_chol);
  for (auto pre : kPreconditioners) {
    SCOPED_TRACE(cloth::to_string(pre));
    int iterations[2];
    for (bool hub : {false, true}) {
      auto pcg = cloth::make_pcg_solver({.tolerance = 1e-10, .hub_block = hub, .preconditioner = pre});
      pcg->analyze(A);
      std::vector<double> x(A.n, 0.0);
      ASSERT_EQ(pcg->solve(A, b.data(), x.data()), cloth::SolveStatus::Ok) << "hub block " << hub;
      EXPECT_LE(max_abs_diff(x, x_chol), 1e-7 * nrm) << "hub block " << hub;
      // The stiff springs make SSOR's carried residual drift (A t is a difference of terms far
      // larger than itself); the reported one must still be the true one.
      EXPECT_LE(relative_residual(A, b, x), 1.01e-10) << "hub block " << hub;
      iterations[hub] = pcg->iterations();
    }
    EXPECT_LT(iterations[1], iterations[0]) << "with " << iterations[1] << ", without " << iterations[0];
  }
}

// A guess off only in the proxies' rows (a contact changed, the cloth where it was): PCG settles
// the preconditioner's dense block (the proxies and the vertices they hold) with the rest held
// before it iterates, and here that is the answer itself: no iteration, CHOLMOD's solution.
// Without that first step the PCG took an iteration here for what the block solves exactly.
TEST(Solver, PcgSettlesTheProxiesRowsBeforeItIterates) {
  std::mt19937 rng(14);
  PinchedSheet p(rng);
  press_triangles(p, {100, 101, 125});
  const auto [A, b, x_chol] = cholmod_reference(p.system_matrix(), rng);
  for (auto pre : kPreconditioners) {
    SCOPED_TRACE(cloth::to_string(pre));
    auto pcg = cloth::make_pcg_solver({.tolerance = 1e-8, .preconditioner = pre});
    pcg->analyze(A);
    std::vector<double> x = x_chol;
    for (int i = A.n - 6; i < A.n; ++i) x[i] += 1e-3;  // the two proxies' rows, 1 mm/s off
    ASSERT_EQ(pcg->solve(A, b.data(), x.data()), cloth::SolveStatus::Ok);
    EXPECT_EQ(pcg->iterations(), 0);
    EXPECT_LE(max_abs_diff(x, x_chol), 1e-7 * max_abs(x_chol));
    EXPECT_LE(relative_residual(A, b, x), 1e-8);
  }
}

// settle_changed solves the dense block alone (the proxies and the vertices they hold), the rest
// of the guess held, with no iteration; resolve() then takes the whole system from there to
// CHOLMOD's answer.
TEST(Solver, PcgSettleChangedSolvesTheProxiesBlockAlone) {
  std::mt19937 rng(16);
  PinchedSheet p(rng);
  press_triangles(p, {100, 101, 125});
  const auto [A, b, x_chol] = cholmod_reference(p.system_matrix(), rng);
  auto pcg = cloth::make_pcg_solver({.tolerance = 1e-8});
  pcg->analyze(A);
  ASSERT_TRUE(pcg->settles_locally());  // the pattern has hub rows
  std::vector<double> x(A.n, 0.0);
  ASSERT_EQ(pcg->solve(A, b.data(), x.data()), cloth::SolveStatus::Ok);
  // A solved guess is left exactly as it is: its block's rows are within the goal already.
  const std::vector<double> solved = x;
  const int no_rows = 0;
  ASSERT_EQ(pcg->settle_changed(A, &no_rows, 0, b.data(), x.data()), cloth::SolveStatus::Ok);
  EXPECT_EQ(x, solved);
  std::vector<double> guess = x_chol;
  for (double& v : guess) v *= 0.9;  // off everywhere
  std::vector<double> settled = guess;
  ASSERT_EQ(pcg->settle_changed(A, &no_rows, 0, b.data(), settled.data()), cloth::SolveStatus::Ok);
  EXPECT_EQ(pcg->iterations(), 0);
  // The proxies' rows (the last two block rows) are solved with the rest held: their residual
  // is gone, and a vertex far from the pinch (block row 0) is as it was.
  std::vector<double> Ax(A.n, 0.0);
  A.multiply(settled.data(), Ax.data());
  for (int i = A.n - 6; i < A.n; ++i) EXPECT_NEAR(b[i] - Ax[i], 0.0, 1e-9 * max_abs(b)) << i;
  for (int i = 0; i < 3; ++i) EXPECT_EQ(settled[i], guess[i]);
  EXPECT_GT(max_abs_diff(settled, guess), 0.0);
  ASSERT_EQ(pcg->resolve(A, b.data(), settled.data()), cloth::SolveStatus::Ok);
  EXPECT_LE(max_abs_diff(settled, x_chol), 1e-6 * max_abs(x_chol));
}

// Over-relaxed SSOR (omega > 1 on the cloth's rows, the fingertips' block whole) solves the
// pinched sheet's system to CHOLMOD's answer, its reported residual the true one.
TEST(Solver, SsorOverRelaxedMatchesCholmod) {
  std::mt19937 rng(10);
  PinchedSheet p(rng);
  press_triangles(p, {100, 101, 125});
  const auto [A, b, x_chol] = cholmod_reference(p.system_matrix(), rng);
  for (double omega : {1.0, 1.3, 1.7}) {
    for (bool float_matrix : {false, true}) {
      SCOPED_TRACE(testing::Message() << "omega " << omega << " float " << float_matrix);
      std::vector<double> x(A.n, 0.0);
      auto pcg = cloth::make_pcg_solver({.tolerance = 1e-10, .single_precision_matrix = float_matrix, .ssor_omega = omega});
      pcg->analyze(A);
      ASSERT_EQ(pcg->solve(A, b.data(), x.data()), cloth::SolveStatus::Ok);
      EXPECT_EQ(pcg->precision_fallbacks(), 0);  // the float copy converges on its own matrix
      EXPECT_LE(max_abs_diff(x, x_chol), (float_matrix ? 1e-5 : 1e-7) * max_abs(x_chol));
      if (!float_matrix) {
        EXPECT_LE(relative_residual(A, b, x), 1.01e-10);
      }
    }
    // At the scenes' tolerances no check afresh: the carried residual alone must be true.
    for (double tol : {1e-2, 1e-3}) {
      std::vector<double> x(A.n, 0.0);
      auto pcg = cloth::make_pcg_solver({.tolerance = tol, .ssor_omega = omega});
      pcg->analyze(A);
      ASSERT_EQ(pcg->solve(A, b.data(), x.data()), cloth::SolveStatus::Ok);
      EXPECT_LE(relative_residual(A, b, x), 1.01 * tol) << "omega " << omega;
      EXPECT_NEAR(relative_residual(A, b, x), pcg->residual(), 1e-3 * tol) << "omega " << omega;
      if (tol == 1e-3) {
        EXPECT_GE(pcg->iterations(), 8) << "a sweep must take r afresh (kRefresh)";
      }
    }
  }
  EXPECT_THROW(cloth::make_pcg_solver({.ssor_omega = 2.0}), std::invalid_argument);
  EXPECT_THROW(cloth::make_pcg_solver({.ssor_omega = 0.9}), std::invalid_argument);
}

// A contact revision changes the springs, so the matrix changes in the rows of the springs'
// corners and proxies only. PCG told those rows (solve_changed) reloads and re-preconditions
// just them, and must then solve the new system as CHOLMOD does; told none, it would solve the
// old one, which this checks is far enough away to tell.
TEST(Solver, PcgSolveChangedReloadsTheChangedRows) {
  std::mt19937 rng(9);
  PinchedSheet p(rng);
  const auto before = centre_springs({100, 101}, 4), after = centre_springs({101, 140, 141}, 4);
  p.integ->point_springs() = before;
  const cloth::SymCsr A0 = p.system_matrix();
  p.integ->point_springs() = after;
  const cloth::SymCsr A1 = p.system_matrix();
  std::vector<int> rows;
  const int nf = A1.n / 3 - 2;
  for (const auto* set : {&before, &after})
    for (const auto& sp : *set) {
      rows.push_back(nf + sp.proxy);
      for (int k = 0; k < 3; ++k) {
        const int fk = p.sheet.model.free_index[p.sheet.model.elements[sp.tri].v[k]];
        if (fk >= 0) rows.push_back(fk);
      }
    }
  std::sort(rows.begin(), rows.end());
  rows.erase(std::unique(rows.begin(), rows.end()), rows.end());
  const Reference ref = cholmod_reference(A1, rng);
  const std::vector<double>& b = ref.b;
  const std::vector<double>& x_chol = ref.x;
  const double nrm = max_abs(x_chol);
  for (auto pre : kPreconditioners)
  for (bool float_matrix : {false, true}) {
    SCOPED_TRACE(cloth::to_string(pre));
    auto pcg = cloth::make_pcg_solver(
        {.tolerance = 1e-10, .single_precision_matrix = float_matrix, .preconditioner = pre});
    pcg->analyze(A0);
    std::vector<double> x(A0.n, 0.0), x_stale(A0.n, 0.0);
    ASSERT_EQ(pcg->solve(A0, b.data(), x.data()), cloth::SolveStatus::Ok);
    x_stale = x;
    // The rows changed, told: A1's solution.
    ASSERT_EQ(pcg->solve_changed(A1, rows.data(), static_cast<int>(rows.size()), b.data(), x.data()),
              cloth::SolveStatus::Ok);
    double err = 0, stale = 0;
    for (int i = 0; i < A1.n; ++i) {
      err = std::max(err, std::abs(x[i] - x_chol[i]));
      stale = std::max(stale, std::abs(x_stale[i] - x_chol[i]));
    }
    // A float copy solves a matrix within float rounding of A1 (PcgOptions).
    const double bound = (float_matrix ? 1e-5 : 1e-7) * nrm;
    EXPECT_LE(err, bound) << "float matrix " << float_matrix;
    EXPECT_GT(stale, 100.0 * bound) << "the two systems are too close to tell apart";
    EXPECT_EQ(pcg->precision_fallbacks(), 0) << "float matrix " << float_matrix;
    // The rows reloaded and the hubs' blocks of the listed columns read afresh (Bsr::
    // reload_hubs), the copy is the one a fresh solver loads whole: the same solve to the bit.
    auto fresh = cloth::make_pcg_solver(
        {.tolerance = 1e-10, .single_precision_matrix = float_matrix, .preconditioner = pre});
    fresh->analyze(A1);
    std::vector<double> y = x_stale;
    ASSERT_EQ(fresh->solve(A1, b.data(), y.data()), cloth::SolveStatus::Ok);
    EXPECT_EQ(fresh->iterations(), pcg->iterations()) << "float matrix " << float_matrix;
    EXPECT_EQ(y, x) << "float matrix " << float_matrix;
  }
}

TEST(Solver, PcgReportsNonConvergenceAndIndefiniteness) {
  Sheet sheet;
  std::mt19937 rng(8);
  const auto s = random_state(sheet.model, rng, 0.005);
  cloth::IntegratorConfig cfg;
  cloth::Integrator integ(sheet.model, cfg, cloth::make_cholmod_solver());
  const cloth::SymCsr A0 = integ.system_matrix(s, 0.02, cloth::JacobianMode::Spd);
  for (auto pre : kPreconditioners) {
    SCOPED_TRACE(cloth::to_string(pre));
    cloth::SymCsr A = A0;
    std::vector<double> b(A.n, 1.0), x(A.n, 0.0);
    cloth::PcgOptions po;
    po.tolerance = 1e-12;
    po.max_iterations = 2;
    po.preconditioner = pre;
    auto pcg = cloth::make_pcg_solver(po);
    pcg->analyze(A);
    EXPECT_EQ(pcg->solve(A, b.data(), x.data()), cloth::SolveStatus::NotConverged);
    for (auto& v : A.val) v = -v;  // negative definite
    std::fill(x.begin(), x.end(), 0.0);
    EXPECT_EQ(pcg->solve(A, b.data(), x.data()), cloth::SolveStatus::NotPositiveDefinite);
    auto chol = cloth::make_cholmod_solver();
    chol->analyze(A);
    EXPECT_EQ(chol->solve(A, b.data(), x.data()), cloth::SolveStatus::NotPositiveDefinite);
  }
}

// The single-precision copy of the matrix: the solve still meets a 1e-4 tolerance measured
// with the double matrix (float rounding, 6e-8 relative, is far below it), and it agrees
// with CHOLMOD to that tolerance times the condition of the step.
TEST(Solver, PcgWithFloatMatrixMeetsToleranceOnTheDoubleMatrix) {
  Sheet sheet;
  std::mt19937 rng(11);
  const auto [A, b, x1] = cholmod_reference(sheet, rng, 0.005);
  for (auto pre : kPreconditioners) {
    SCOPED_TRACE(cloth::to_string(pre));
    const auto [pcg, x2, st] = pcg_solve(A, b, {.tolerance = 1e-4, .single_precision_matrix = true, .preconditioner = pre});
    ASSERT_EQ(st, cloth::SolveStatus::Ok);
    EXPECT_GT(pcg->iterations(), 1);
    EXPECT_LE(pcg->residual(), 1e-4);
    EXPECT_LE(relative_residual(A, b, x2), 1.01e-4);
    double err = 0, nrm = 0;
    for (int i = 0; i < A.n; ++i) {
      err += (x1[i] - x2[i]) * (x1[i] - x2[i]);
      nrm += x1[i] * x1[i];
    }
    EXPECT_LE(std::sqrt(err / nrm), 1e-3);
    EXPECT_GT(std::sqrt(err / nrm), 0.0);
  }
}

namespace {

// P A P^T for the block renumbering `to` (old block row -> new).
cloth::SymCsr renumber_blocks(const cloth::SymCsr& A, const std::vector<int>& to) {
  const int n = A.n;
  std::vector<std::vector<std::pair<int, double>>> rows(n);
  for (int r = 0; r < n; ++r)
    for (int k = A.rowptr[r]; k < A.rowptr[r + 1]; ++k)
      rows[3 * to[r / 3] + r % 3].push_back({3 * to[A.col[k] / 3] + A.col[k] % 3, A.val[k]});
  cloth::SymCsr P;
  P.n = n;
  P.block3 = A.block3;
  P.rowptr.push_back(0);
  for (auto& row : rows) {
    std::sort(row.begin(), row.end());
    for (const auto& [c, v] : row) {
      P.col.push_back(c);
      P.val.push_back(v);
    }
    P.rowptr.push_back(static_cast<int>(P.col.size()));
  }
  return P;
}

// diag(A, B): two pieces of cloth in one system.
cloth::SymCsr two_pieces(const cloth::SymCsr& A, const cloth::SymCsr& B) {
  cloth::SymCsr D;
  D.n = A.n + B.n;
  D.block3 = A.block3 && B.block3;
  D.rowptr.push_back(0);
  for (int piece = 0; piece < 2; ++piece) {
    const cloth::SymCsr* M = piece == 0 ? &A : &B;
    const int shift = piece == 0 ? 0 : A.n;
    for (int r = 0; r < M->n; ++r) {
      for (int k = M->rowptr[r]; k < M->rowptr[r + 1]; ++k) {
        D.col.push_back(M->col[k] + shift);
        D.val.push_back(M->val[k]);
      }
      D.rowptr.push_back(static_cast<int>(D.col.size()));
    }
  }
  return D;
}

}  // namespace

// SSOR's sweeps share each iteration with a second thread (the integrator's pool): two parts of
// the cloth that share no block at once, their separator alone. Whether or not the pool is
// there, and whichever thread takes a part, the solve is the same to the last bit, and
// CHOLMOD's. The sheet is split as numbered (a grid's halves), renumbered at random (split by
// breadth-first levels), and doubled (two pieces of cloth, each with its fingertips).
TEST(Solver, SsorOnTwoThreadsIsTheSolveOnOne) {
  std::mt19937 rng(12);
  PinchedSheet p(rng);
  press_triangles(p, {100, 101, 125});
  const cloth::SymCsr A = p.system_matrix();
  const int nb = A.n / 3;
  std::vector<int> shuffled(nb);
  std::iota(shuffled.begin(), shuffled.end(), 0);
  std::shuffle(shuffled.begin(), shuffled.end() - 2, rng);  // the proxies stay last
  const std::pair<const char*, cloth::SymCsr> systems[] = {
      {"grid order", A}, {"shuffled", renumber_blocks(A, shuffled)}, {"two pieces", two_pieces(A, A)}};
  cloth::WorkerPool pool;
  for (const auto& [name, M] : systems) {
    for (bool float_matrix : {false, true}) {
      SCOPED_TRACE(testing::Message() << name << ", float " << float_matrix);
      const Reference ref = cholmod_reference(M, rng);
      const cloth::PcgOptions po{.tolerance = 1e-10, .single_precision_matrix = float_matrix};
      const PcgRun one = pcg_solve(M, ref.b, po);
      ASSERT_EQ(one.st, cloth::SolveStatus::Ok);
      EXPECT_LE(max_abs_diff(one.x, ref.x), (float_matrix ? 1e-5 : 1e-7) * max_abs(ref.x));
      // Three rounds, and more (for up to 2 s) until the helper has swept a part: under load
      // (ctest -j2) the caller may take both before the helper runs.
      std::uint64_t helper_sweeps = 0;
      const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(2);
      for (int round = 0;
           round < 3 || (helper_sweeps == 0 && std::chrono::steady_clock::now() < give_up);
           ++round) {
        auto two = cloth::make_pcg_solver(po);
        two->use_pool(&pool);
        two->analyze(M);
        std::vector<double> x(M.n, 0.0);
        const cloth::WorkerPool::Burst burst(round % 2 ? &pool : nullptr);  // spinning or woken
        ASSERT_EQ(two->solve(M, ref.b.data(), x.data()), cloth::SolveStatus::Ok);
        EXPECT_EQ(two->iterations(), one.pcg->iterations()) << "round " << round;
        EXPECT_EQ(x, one.x) << "round " << round;
        helper_sweeps += two->helper_sweeps();
      }
      EXPECT_GT(helper_sweeps, 0u) << "the helper never swept a part";
    }
  }
}
