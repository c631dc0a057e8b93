#include "app/kes.hpp"
#include "log/input_file.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <stdexcept>
#include <utility>

#include <nlohmann/json.hpp>

#include "app/toml_file.hpp"
#include "cloth/mesh.hpp"
#include "cloth/model.hpp"
#include "cloth/statics.hpp"
#include "log/device_log.hpp"

namespace hapticloth::app {

using cloth::Vec3;

namespace {
// Each test with its name, once: to_string and parse_kes_test both read it.
constexpr std::pair<KesTest, const char*> kKesTests[] = {
    {KesTest::Weft, "weft"}, {KesTest::Warp, "warp"}, {KesTest::Shear, "shear"}};
}  // namespace

KesTest parse_kes_test(const std::string& name) {
  for (const auto& [test, test_name] : kKesTests)
    if (name == test_name) return test;
  throw std::invalid_argument("unknown test '" + name + "' (weft, warp, shear)");
}

const char* to_string(KesTest t) {
  for (const auto& [test, test_name] : kKesTests)
    if (t == test) return test_name;
  return "?";
}

namespace {

constexpr double kInvSqrt2 = 0.70710678118654752440;
constexpr double kGauge = 0.20;  // m: tensile gauge length / shear clamp length (KES-F)
constexpr double kWidth = 0.05;  // m: tensile strip width / shear clamp gap

struct Specimen {
  cloth::Mesh mesh;
  std::vector<int> fixed, moving;  // clamp vertices
  std::vector<double> weight;      // per moving vertex: share of the measured clamp length
  double measured_length = 0.0;    // m of clamp the reaction is measured over
};

// Continuation predictor: extrapolate the free vertices linearly from the last two equilibria.
void predict(const cloth::ClothModel& m, const cloth::ClothState& prev, cloth::ClothState& cur) {
  for (int i = 0; i < m.num_vertices(); ++i)
    if (!m.pinned[i]) cur.x[i] = 2.0 * cur.x[i] - prev.x[i];
}

cloth::StaticResult equilibrate(cloth::StaticSolver& solver, cloth::ClothState& s, KesResult& r,
                                const std::string& where) {
  cloth::StaticOptions so;
  so.force_tolerance = 1e-10;
  so.max_iterations = 60;
  const auto res = solver.solve(s, so);
  if (!res.converged) {
    r.converged = false;
    std::ostringstream os;
    os << "kes: no equilibrium at " << where << " after " << res.iterations
       << " Newton iterations (residual " << res.residual << " N)";
    throw std::runtime_error(os.str());
  }
  return res;
}

// Reaction per unit length on the moving clamp: -(net cloth force) summed with weights.
Vec3 reaction(const cloth::StaticSolver& solver, const cloth::ClothState& s, const Specimen& sp,
              std::vector<Vec3>& f) {
  solver.net_forces(s, f);
  Vec3 R = Vec3::Zero();
  for (size_t k = 0; k < sp.moving.size(); ++k) R -= sp.weight[k] * f[sp.moving[k]];
  return R / sp.measured_length;
}

double bisect_strain(const cloth::StrainStressCurve& c, double target, double hi) {
  double lo = 0.0;
  if (c.stress(hi) < target) throw std::runtime_error("kes: lateral tension above the warp curve's range");
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (c.stress(mid) < target ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

void finish(KesResult& r) {
  std::sort(r.points.begin(), r.points.end(),
            [](const KesPoint& a, const KesPoint& b) { return a.strain < b.strain; });
  double s2 = 0.0, mx = 0.0, ms = 0.0;
  for (const auto& p : r.points) {
    const double d = p.stress - p.material;
    s2 += d * d;
    mx = std::max(mx, std::abs(d));
    ms = std::max(ms, std::abs(p.material));
  }
  r.material_rms = r.points.empty() ? 0.0 : std::sqrt(s2 / r.points.size());
  r.material_max = mx;
  r.max_stress = ms;
}

KesResult run_tensile(const cloth::Material& mat, KesTest test, const KesOptions& opt) {
  const bool weft = test == KesTest::Weft;
  const cloth::StrainStressCurve& curve = weft ? mat.weft : mat.warp;
  const double emax = opt.max_strain > 0.0 ? opt.max_strain : curve.max_strain;
  cloth::GridSpec g;
  const int nl = std::max(4, static_cast<int>(std::lround(kGauge * 100 * opt.cells_per_cm)));
  const int nw = std::max(2, static_cast<int>(std::lround(kWidth * 100 * opt.cells_per_cm)));
  // The loading direction is the weave direction under test: u = x for weft, v = y for warp.
  g.width = weft ? kGauge : kWidth;
  g.height = weft ? kWidth : kGauge;
  g.nx = weft ? nl : nw;
  g.ny = weft ? nw : nl;
  g.origin = Vec3::Zero();
  Specimen sp;
  sp.mesh = cloth::make_grid(g);
  sp.fixed = cloth::grid_edge(sp.mesh, weft ? "left" : "bottom");
  sp.moving = cloth::grid_edge(sp.mesh, weft ? "right" : "top");
  // The whole clamp: under uniaxial tension the strip stays uniform (the laws have no Poisson
  // coupling, section 3.2); each node's force is already its tributary share of the width.
  sp.weight.assign(sp.moving.size(), 1.0);
  sp.measured_length = kWidth;
  std::vector<int> pins = sp.fixed;
  pins.insert(pins.end(), sp.moving.begin(), sp.moving.end());
  const cloth::ClothModel model = cloth::build_model(sp.mesh, mat, pins);
  cloth::StaticSolver solver(model, Vec3::Zero());
  const Vec3 dir = weft ? Vec3(1, 0, 0) : Vec3(0, 1, 0);

  KesResult r;
  r.test = test;
  r.triangles = model.num_triangles();
  cloth::ClothState s = cloth::rest_state(model), prev = s;
  std::vector<Vec3> f;
  r.points.push_back(KesPoint{0.0, 0.0, 0.0, 0.0, curve.stress(0.0), 0, 0.0});
  for (int k = 1; k <= opt.load_steps; ++k) {
    const double e = emax * k / opt.load_steps;
    cloth::ClothState guess = s;
    if (k >= 2) {
      predict(model, prev, guess);
    } else {  // first step: the affine stretch as the predictor
      for (int i = 0; i < model.num_vertices(); ++i)
        guess.x[i] = model.rest_positions[i] + e * model.rest_positions[i].dot(dir) * dir;
    }
    for (int v : sp.moving) guess.x[v] = model.rest_positions[v] + e * kGauge * dir;
    const auto res = equilibrate(solver, guess, r, "strain " + std::to_string(e));
    prev = s;
    s = guess;
    const Vec3 R = reaction(solver, s, sp, f);
    KesPoint p;
    p.strain = e;
    p.stress = R.dot(dir);
    p.clamp_force = p.stress;
    p.material = curve.stress(e);
    p.newton_iterations = res.iterations;
    p.residual = res.residual;
    r.points.push_back(p);
  }
  finish(r);
  return r;
}

// KES-F shear specimen: clamps along the weft (u = x) 20 cm long, 5 cm apart across the warp
// (v = y).
Specimen shear_specimen(const KesOptions& opt) {
  cloth::GridSpec g;
  g.width = kGauge;
  g.height = kWidth;
  g.nx = std::max(8, 4 * static_cast<int>(std::lround(kGauge * 100 * opt.cells_per_cm / 4.0)));
  g.ny = std::max(2, static_cast<int>(std::lround(kWidth * 100 * opt.cells_per_cm)));
  Specimen sp;
  sp.mesh = cloth::make_grid(g);
  sp.fixed = cloth::grid_edge(sp.mesh, "bottom");
  sp.moving = cloth::grid_edge(sp.mesh, "top");
  // Measured over the middle half of the clamp: the free side edges carry no shear traction, so
  // the shear stress falls off within a few centimetres of them (as on the real tester).
  const int nx = g.nx;
  for (int k = 0; k <= nx; ++k) {
    double w = 0.0;
    if (k > nx / 4 && k < 3 * nx / 4) w = 1.0;
    if (k == nx / 4 || k == 3 * nx / 4) w = 0.5;
    sp.weight.push_back(w);
  }
  sp.measured_length = 0.5 * kGauge;
  return sp;
}

// Guarded sides: the side edges follow the affine shear, as the middle of an infinitely wide
// specimen would. With free sides the disturbance of this orthotropic membrane (no Poisson
// coupling, stiff fibres, soft shear) reaches far into a 20 cm x 5 cm specimen and the clamp
// force deviates from the law (docs/kes.md, 'Simulated Kawabata tests'; --free-edges shows it).
std::vector<int> guarded_sides(const Specimen& sp, bool free_edges) {
  std::vector<int> sides;
  if (!free_edges)
    for (const char* e : {"left", "right"})
      for (int v : cloth::grid_edge(sp.mesh, e)) sides.push_back(v);
  return sides;
}

// The affine map of the clamp motion (shear sh, gap strain e) at a rest point.
Vec3 affine(const Vec3& p, double sh, double e) {
  return Vec3(p.x() + sh * p.y(), p.y() * (1.0 + e), p.z());
}

// What every step of the shear test works on.
struct ShearRun {
  const cloth::Material& mat;
  const KesOptions& opt;
  const cloth::ClothModel& model;
  cloth::StaticSolver& solver;
  const Specimen& sp;
  const std::vector<int>& sides;  // moved with the clamp (guarded sides)
  KesResult& r;
  std::vector<Vec3> f;            // scratch: net forces
};

// The specimen at rest under the lateral tension (clamp gap strain e0), before shearing.
cloth::ClothState pretension(ShearRun& run, double e0) {
  cloth::ClothState s0 = cloth::rest_state(run.model);
  for (int i = 0; i < run.model.num_vertices(); ++i) s0.x[i] = affine(run.model.rest_positions[i], 0.0, e0);
  equilibrate(run.solver, s0, run.r, "lateral tension");
  return s0;
}

// The equilibrium at shear sh under constant lateral tension (the tester's weight): the clamp
// gap strain `gap` follows so that the clamp's force across it stays T. Secant steps on the gap,
// from the last one. R is the clamp reaction per unit length.
cloth::StaticResult hold_tension(ShearRun& run, double sh, double gam, double& gap,
                                 cloth::ClothState& guess, Vec3& R) {
  cloth::StaticResult res;
  double e_lo = gap, f_lo = 0.0;
  bool have_lo = false;
  for (int tries = 0;; ++tries) {
    for (int v : run.sp.moving) guess.x[v] = affine(run.model.rest_positions[v], sh, gap);
    for (int v : run.sides) guess.x[v] = affine(run.model.rest_positions[v], sh, gap);
    res = equilibrate(run.solver, guess, run.r, "shear angle " + std::to_string(gam) + " rad");
    R = reaction(run.solver, guess, run.sp, run.f);
    const double err = R.y() - run.opt.lateral_tension;
    if (std::abs(err) <= 1e-9 * run.opt.lateral_tension || tries == 20) break;
    double slope = run.mat.warp.stiffness(gap);  // first guess: the warp law's tangent
    if (have_lo && gap != e_lo) slope = (R.y() - f_lo) / (gap - e_lo);
    if (!(slope > 0.0)) slope = std::max(run.mat.warp.B[0][1], 1e-6);
    e_lo = gap;
    f_lo = R.y();
    have_lo = true;
    gap -= err / slope;
  }
  return res;
}

// The point of one equilibrium at clamp angle gam (shear sh = tan gam, gap strain e0).
KesPoint shear_point(const cloth::Material& mat, double gam, double sh, double e0, const Vec3& R,
                     const cloth::StaticResult& res) {
  // Work-conjugate stresses of the homogeneous state with U = (1, 0), V = (sh, 1 + e0):
  //   [f_u, f_v] = [[d|V|/d sh, d eps_uv/d sh], [d|V|/d e, d eps_uv/d e]] [sigma_vv, sigma_uv]
  // (eq. 4: eps_uv = (|U + V| - |U - V|) / sqrt 2); solved for sigma_uv, so that the lateral
  // tension's share of the clamp force (T tan(angle) on the tester) is taken out.
  const double ee = 1.0 + e0;
  const double Vn = std::hypot(sh, ee), Sn = std::hypot(1.0 + sh, ee), Dn = std::hypot(1.0 - sh, ee);
  const double a11 = sh / Vn, a12 = ((1.0 + sh) / Sn + (1.0 - sh) / Dn) * kInvSqrt2;
  const double a21 = ee / Vn, a22 = (ee / Sn - ee / Dn) * kInvSqrt2;
  const double det = a11 * a22 - a12 * a21;
  const double sigma_uv = (a11 * R.y() - a21 * R.x()) / det;
  KesPoint p;
  p.angle = gam;
  p.strain = (Sn - Dn) * kInvSqrt2;
  p.stress = sigma_uv;
  p.clamp_force = R.x();
  p.material = mat.shear.stress(p.strain);
  p.newton_iterations = res.iterations;
  p.residual = res.residual;
  return p;
}

// One branch of the sweep from the pre-tensioned state s0: sign +1 from 0 to +max degrees,
// -1 from one step below 0 to -max.
void sweep_shear(ShearRun& run, const cloth::ClothState& s0, double e0, int sign) {
  const double gmax = run.opt.max_shear_deg * M_PI / 180.0;
  cloth::ClothState s = s0, prev = s0;
  double gap = e0;  // clamp gap strain, adjusted to hold the tension
  for (int k = (sign > 0 ? 0 : 1); k <= run.opt.load_steps; ++k) {
    const double gam = sign * gmax * k / run.opt.load_steps;
    const double sh = std::tan(gam);
    cloth::ClothState guess = s;
    if (k >= 2) predict(run.model, prev, guess);
    Vec3 R;
    const cloth::StaticResult res = hold_tension(run, sh, gam, gap, guess, R);
    prev = s;
    s = guess;
    run.r.points.push_back(shear_point(run.mat, gam, sh, gap, R, res));
  }
}

// KES-F shear: the specimen is held at a lateral tension across the clamps, then one clamp
// slides along its length, both ways.
KesResult run_shear(const cloth::Material& mat, const KesOptions& opt) {
  const Specimen sp = shear_specimen(opt);
  const std::vector<int> sides = guarded_sides(sp, opt.free_edges);
  std::vector<int> pins = sp.fixed;
  pins.insert(pins.end(), sp.moving.begin(), sp.moving.end());
  pins.insert(pins.end(), sides.begin(), sides.end());
  const cloth::ClothModel model = cloth::build_model(sp.mesh, mat, pins);
  cloth::StaticSolver solver(model, Vec3::Zero());

  KesResult r;
  r.test = KesTest::Shear;
  r.triangles = model.num_triangles();
  ShearRun run{mat, opt, model, solver, sp, sides, r, {}};
  // Lateral tension: the clamp gap that gives sigma_vv = T before shearing.
  const double e0 = bisect_strain(mat.warp, opt.lateral_tension, std::max(mat.warp.max_strain, 0.5));
  const cloth::ClothState s0 = pretension(run, e0);
  for (int sign : {+1, -1}) sweep_shear(run, s0, e0, sign);
  finish(r);
  return r;
}

}  // namespace

KesResult run_kes(const cloth::Material& m, KesTest test, const KesOptions& opt) {
  if (opt.load_steps < 2 || opt.load_steps > 10000)
    throw std::invalid_argument("kes: load steps must be in [2, 10000]");
  if (opt.cells_per_cm < 1 || opt.cells_per_cm > 20)
    throw std::invalid_argument("kes: cells per cm must be in [1, 20]");
  if (test == KesTest::Shear) return run_shear(m, opt);
  return run_tensile(m, test, opt);
}

void compare_measured(KesResult& r, const KesMeasured& meas) {
  if (r.points.size() < 2) return;
  double s2 = 0.0, mx = 0.0, ms = 0.0;
  int n = 0;
  for (size_t i = 0; i < meas.strain.size(); ++i) {
    const double e = meas.strain[i];
    if (e < r.points.front().strain || e > r.points.back().strain) continue;
    auto it = std::lower_bound(r.points.begin(), r.points.end(), e,
                               [](const KesPoint& p, double x) { return p.strain < x; });
    if (it == r.points.begin()) ++it;
    const KesPoint& b = *it;
    const KesPoint& a = *(it - 1);
    const double t = (b.strain > a.strain) ? (e - a.strain) / (b.strain - a.strain) : 0.0;
    const double sim = a.stress + t * (b.stress - a.stress);
    const double d = sim - meas.stress[i];
    s2 += d * d;
    mx = std::max(mx, std::abs(d));
    ms = std::max(ms, std::abs(meas.stress[i]));
    ++n;
  }
  if (n == 0) return;
  r.measured_rms = std::sqrt(s2 / n);
  r.measured_max = mx;
  r.measured_max_stress = ms;
}

KesMeasured load_measured(const std::string& path, KesTest test) {
  if (std::string e = devices::check_input_file(path, devices::kMaxDataBytes); !e.empty())
    throw ConfigError(e);
  std::ifstream in(path);
  if (!in) throw ConfigError(path + ": cannot open the measured CSV");
  auto fail = [&](int line, const std::string& msg) {
    throw ConfigError(path + ":" + std::to_string(line) + ": " + msg);
  };
  KesMeasured m;
  std::string line;
  int ln = 0;
  bool header = false;
  int ct = -1, cs = -1, cv = -1;
  while (std::getline(in, line)) {
    ++ln;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    const std::vector<std::string> cols = devices::split_csv(line);
    if (!header) {
      for (int i = 0; i < static_cast<int>(cols.size()); ++i) {
        if (cols[i] == "test") ct = i;
        if (cols[i] == "strain") cs = i;
        if (cols[i] == "stress") cv = i;
      }
      if (ct < 0 || cs < 0 || cv < 0) fail(ln, "expected the header row 'test,strain,stress'");
      header = true;
      continue;
    }
    const int need = std::max({ct, cs, cv}) + 1;
    if (static_cast<int>(cols.size()) < need)
      fail(ln, "expected " + std::to_string(need) + " columns, got " + std::to_string(cols.size()));
    const std::string& t = cols[ct];
    if (t != "weft" && t != "warp" && t != "shear") fail(ln, "unknown test '" + t + "' (weft, warp, shear)");
    if (t != to_string(test)) continue;
    auto num = [&](const std::string& s, const char* what) {
      char* end = nullptr;
      const double v = std::strtod(s.c_str(), &end);
      if (s.empty() || *end != '\0' || !std::isfinite(v)) fail(ln, std::string(what) + " '" + s + "' is not a number");
      return v;
    };
    const double e = num(cols[cs], "strain"), sg = num(cols[cv], "stress");
    if (!m.strain.empty() && !(e > m.strain.back())) fail(ln, "strain must increase within a test");
    m.strain.push_back(e);
    m.stress.push_back(sg);
  }
  if (!header) throw ConfigError(path + ": no header row 'test,strain,stress'");
  if (m.strain.size() < 2) throw ConfigError(path + ": fewer than 2 points for test '" + std::string(to_string(test)) + "'");
  return m;
}

namespace {
double pct(double v, double ref) { return ref > 0.0 ? 100.0 * v / ref : 0.0; }
}  // namespace

std::string kes_to_json(const KesResult& r) {
  nlohmann::json j;
  j["test"] = to_string(r.test);
  j["triangles"] = r.triangles;
  j["points"] = r.points.size();
  j["max_stress"] = r.max_stress;
  j["material_rms"] = r.material_rms;
  j["material_max"] = r.material_max;
  j["material_rms_pct"] = pct(r.material_rms, r.max_stress);
  j["material_max_pct"] = pct(r.material_max, r.max_stress);
  if (r.measured_rms >= 0.0) {
    j["measured_rms"] = r.measured_rms;
    j["measured_max"] = r.measured_max;
    j["measured_rms_pct"] = pct(r.measured_rms, r.measured_max_stress);
    j["measured_max_pct"] = pct(r.measured_max, r.measured_max_stress);
  }
  int it = 0;
  double res = 0.0;
  for (const auto& p : r.points) {
    it = std::max(it, p.newton_iterations);
    res = std::max(res, p.residual);
  }
  j["newton_iterations_max"] = it;
  j["residual_max_n"] = res;
  auto& c = j["curve"] = nlohmann::json::array();
  for (const auto& p : r.points) c.push_back({p.strain, p.stress, p.material});
  return j.dump();
}

std::string kes_to_text(const KesResult& r) {
  std::ostringstream os;
  os << std::setprecision(4);
  os << "test             " << to_string(r.test) << " (" << r.triangles << " triangles, "
     << r.points.size() << " equilibrium points)\n";
  os << "max stress       " << r.max_stress << " N/m\n";
  os << "vs material law  rms " << r.material_rms << " N/m (" << pct(r.material_rms, r.max_stress)
     << "%), max " << r.material_max << " N/m (" << pct(r.material_max, r.max_stress) << "%)\n";
  if (r.measured_rms >= 0.0)
    os << "vs measured      rms " << r.measured_rms << " N/m ("
       << pct(r.measured_rms, r.measured_max_stress) << "%), max " << r.measured_max << " N/m ("
       << pct(r.measured_max, r.measured_max_stress) << "%)\n";
  return os.str();
}

std::string kes_to_csv(const KesResult& r) {
  std::ostringstream os;
  os << std::setprecision(10);
  os << "strain,angle_rad,stress_n_per_m,clamp_force_n_per_m,material_n_per_m\n";
  for (const auto& p : r.points)
    os << p.strain << ',' << p.angle << ',' << p.stress << ',' << p.clamp_force << ','
       << p.material << '\n';
  return os.str();
}

}  // namespace hapticloth::app
