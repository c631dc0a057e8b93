// hapticloth-bench limit: our whole cloth step against CHOLMOD's own factorization and solve
// of the same system matrix (eq. 9), per mesh size, with the factorization's flop count.
#include <suitesparse/cholmod.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>
#include <random>

#include "accuracy.hpp"
#include "bench_common.hpp"

namespace hapticloth::bench {

using nlohmann::json;

namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// CHOLMOD on its own: analyze once, then factorize and solve `reps` times; medians in ms.
json cholmod_alone(const cloth::SymCsr& A, bool supernodal, int reps) {
  cholmod_common c;
  cholmod_start(&c);
  c.supernodal = supernodal ? CHOLMOD_SUPERNODAL : CHOLMOD_SIMPLICIAL;
  cholmod_sparse h{};
  h.nrow = h.ncol = A.n;
  h.nzmax = A.nnz();
  h.p = const_cast<int*>(A.rowptr.data());
  h.i = const_cast<int*>(A.col.data());
  h.x = const_cast<double*>(A.val.data());
  h.stype = 1;  // both triangles stored; CHOLMOD reads the upper one
  h.itype = CHOLMOD_INT;
  h.xtype = CHOLMOD_REAL;
  h.dtype = CHOLMOD_DOUBLE;
  h.sorted = 1;
  h.packed = 1;
  auto t0 = std::chrono::steady_clock::now();
  cholmod_factor* L = cholmod_analyze(&h, &c);
  const double analyze_ms = ms_since(t0);
  const double flops = c.fl, lnz = c.lnz;
  cholmod_dense* b = cholmod_ones(A.n, 1, CHOLMOD_REAL, &c);
  std::vector<double> fact, solve;
  for (int r = 0; r < reps; ++r) {
    t0 = std::chrono::steady_clock::now();
    cholmod_factorize(&h, L, &c);
    fact.push_back(ms_since(t0));
    t0 = std::chrono::steady_clock::now();
    cholmod_dense* x = cholmod_solve(CHOLMOD_A, L, b, &c);
    solve.push_back(ms_since(t0));
    cholmod_free_dense(&x, &c);
  }
  const bool ok = c.status == CHOLMOD_OK;
  cholmod_free_dense(&b, &c);
  cholmod_free_factor(&L, &c);
  cholmod_finish(&c);
  const double f = median(fact), s = median(solve);
  return {{"analyze_ms", analyze_ms}, {"factorize_ms", f}, {"solve_ms", s},
          {"factorize_and_solve_ms", f + s}, {"flops", flops}, {"nnz_L", lnz},
          {"gflop_per_s", f > 0 ? flops / (f * 1e6) : 0.0}, {"ok", ok}};
}

// Our step, medians over `steps` steps from release (ms).
json our_step(const app::Scene& sc, const cloth::ClothModel& m, const std::string& solver, long steps,
              cloth::ClothState* final_state) {
  RunConfig c = default_config(sc);
  c.solver = solver;
  auto integ = make_integrator(sc, m, c);
  cloth::ClothState s = cloth::rest_state(m);
  std::vector<double> total, assemble, solve, its;
  for (long k = 0; k < steps; ++k) {
    integ->step(s);
    const auto& t = integ->last_timing();
    total.push_back(t.total_ms);
    assemble.push_back(t.assemble_ms);
    solve.push_back(t.solve_ms);
    its.push_back(t.iterations);
  }
  if (final_state) *final_state = s;
  json j = {{"step_ms", median(total)}, {"assemble_ms", median(assemble)}, {"solve_ms", median(solve)}};
  if (solver == "pcg") j["iterations"] = median(its);
  return j;
}

}  // namespace

json limit(const LimitOptions& opt) {
  json rows = json::array();
  for (const char* name : {"hanging_square", "hanging_square_4k", "hanging_square_16k"}) {
    const app::Scene sc = app::load_scene(opt.source_dir + "/tools/scenes/" + name + ".toml");
    const cloth::ClothModel m = app::build_model(sc);
    const long steps = opt.quick ? 10 : (m.num_triangles() > 10000 ? 40 : 200);
    if (opt.verbose) std::cerr << "limit: " << name << " (" << m.num_triangles() << " triangles)" << std::endl;
    cloth::ClothState s;
    json ours_cholmod = our_step(sc, m, "cholmod", steps, &s);
    json ours_pcg = our_step(sc, m, "pcg", steps, nullptr);
    // The system matrix of eq. 9 at the state the CHOLMOD run ended in.
    RunConfig c = default_config(sc);
    c.solver = "cholmod";
    auto integ = make_integrator(sc, m, c);
    const cloth::SymCsr A = integ->system_matrix(s, sc.integrator.dt, cloth::JacobianMode::Spd);
    const int reps = opt.quick ? 3 : (m.num_triangles() > 10000 ? 10 : 40);
    json simp = cholmod_alone(A, false, reps), super = cholmod_alone(A, true, reps);
    const double best = std::min(simp["factorize_and_solve_ms"].get<double>(),
                                 super["factorize_and_solve_ms"].get<double>());
    rows.push_back({{"scene", name},
                    {"triangles", m.num_triangles()},
                    {"dof", A.n},
                    {"nnz_A", A.nnz()},
                    {"ours_cholmod", ours_cholmod},
                    {"ours_pcg", ours_pcg},
                    {"cholmod_simplicial", simp},
                    {"cholmod_supernodal", super},
                    {"overhead_ratio_cholmod_step", ours_cholmod["step_ms"].get<double>() / best},
                    {"pcg_step_vs_cholmod_alone", ours_pcg["step_ms"].get<double>() / best}});
  }
  return {{"benchmark", "limit"}, {"quick", opt.quick}, {"rows", rows}};
}

}  // namespace hapticloth::bench
