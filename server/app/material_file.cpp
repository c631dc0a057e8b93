#include "app/material_file.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>

namespace hapticloth::app {

namespace {

cloth::StrainStressCurve parse_curve(const TomlFile& f, const toml::table& root,
                                     const std::string& key, bool odd) {
  const toml::table* t = f.table(root, "", key, true);
  f.only_keys(*t, key, {"knots", "B", "viscosity", "compression_scale", "max_strain"});
  cloth::StrainStressCurve c;
  c.odd = odd;
  const std::vector<double> knots = f.numbers(*t, key, "knots", 1, 3);
  c.segments = static_cast<int>(knots.size());
  for (int i = 0; i < c.segments; ++i) c.knots[i] = knots[i];

  const toml::node* bn = t->get("B");
  const std::string bk = key + ".B";
  if (!bn) f.fail(t, bk, "missing (an array of one [B_i0, B_i1, B_i2, B_i3] row per knot)");
  const toml::array* rows = bn->as_array();
  if (!rows) f.fail(bn, bk, "expected an array of rows [B_i0, B_i1, B_i2, B_i3]");
  if (rows->size() != knots.size())
    f.fail(bn, bk,
           "expected one row per knot (" + std::to_string(knots.size()) + "), got " +
               std::to_string(rows->size()));
  for (size_t i = 0; i < rows->size(); ++i) {
    const toml::node* rn = rows->get(i);
    const std::string rk = bk + "[" + std::to_string(i) + "]";
    const toml::array* row = rn->as_array();
    if (!row || row->size() != 4) f.fail(rn, rk, "expected 4 numbers [B_i0, B_i1, B_i2, B_i3]");
    for (size_t j = 0; j < 4; ++j) {
      const toml::node* e = row->get(j);
      if (!e->is_number()) f.fail(e, rk + "[" + std::to_string(j) + "]", "expected a number");
      c.B[i][j] = e->value<double>().value();
    }
  }
  c.viscosity = f.number(*t, key, "viscosity", 0.0);
  c.compression_scale = f.number(*t, key, "compression_scale", 1.0);
  const double max_strain = f.number(*t, key, "max_strain", 0.3);
  if (!(max_strain > 0.0)) f.fail(t->get("max_strain"), key + ".max_strain", "must be > 0");
  c.max_strain = max_strain;
  try {
    c.validate("", max_strain);
  } catch (const std::invalid_argument& e) {
    f.fail(t, key, e.what());
  }
  return c;
}

// A surface trace CSV: `distance_m,height_m` rows (a header line and # comments allowed), as
// a KES-FB4 roughness trace gives it. Errors name the CSV's file and line.
cloth::SurfaceProfile read_trace(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw ConfigError(path + ": cannot read the surface trace");
  std::vector<double> d, h;
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    if (line.empty() || line[0] == '#' || line.rfind("distance", 0) == 0) continue;
    std::istringstream row(line);
    std::string a, b, rest;
    double x = 0.0, y = 0.0;
    size_t ia = 0, ib = 0;
    const bool two = std::getline(row, a, ',') && std::getline(row, b, ',') && !std::getline(row, rest, ',');
    auto trim = [](std::string& t) {
      t.erase(0, t.find_first_not_of(" \t\r"));
      t.erase(t.find_last_not_of(" \t\r") + 1);
    };
    trim(a);
    trim(b);
    try {
      x = two ? std::stod(a, &ia) : 0.0;
      y = two ? std::stod(b, &ib) : 0.0;
    } catch (const std::exception&) {
      ia = 0;
    }
    if (!two || ia == 0 || ia != a.size() || ib != b.size() || !std::isfinite(x) || !std::isfinite(y) || std::abs(y) > 2e-3)
      throw ConfigError(path + ":" + std::to_string(n) +
                        ": expected 'distance_m,height_m' (two finite numbers, |height| <= 2 mm), got '" + line + "'");
    if (!d.empty() && !(x > d.back()))
      throw ConfigError(path + ":" + std::to_string(n) + ": distance " + a + " does not increase");
    d.push_back(x);
    h.push_back(y);
  }
  if (d.size() < 8) throw ConfigError(path + ": a surface trace needs at least 8 rows, got " + std::to_string(d.size()));
  return cloth::trace_profile(d, h);
}

// [surface.weft] or [surface.warp]: a weave (yarn_spacing, amplitude, shape) or a measured
// trace (a CSV path, relative to the material file).
void parse_profile(const TomlFile& f, const toml::table& surface, const std::string& dir,
                   cloth::SurfaceProfile& profile, cloth::SurfaceSource& source) {
  const std::string key = "surface." + dir;
  const toml::table* t = f.table(surface, "surface", dir, false);
  if (!t) return;
  f.only_keys(*t, key, {"yarn_spacing", "amplitude", "shape", "trace"});
  if (t->get("trace")) {
    if (t->get("yarn_spacing") || t->get("amplitude") || t->get("shape"))
      f.fail(t->get("trace"), key + ".trace", "give either a trace or a weave (yarn_spacing, amplitude, shape), not both");
    source.trace = f.string(*t, key, "trace");
    const std::filesystem::path at = std::filesystem::path(f.path()).parent_path() / source.trace;
    try {
      profile = read_trace(at.string());
    } catch (const ConfigError& e) {
      f.fail(t->get("trace"), key + ".trace", e.what());
    } catch (const std::invalid_argument& e) {
      f.fail(t->get("trace"), key + ".trace", at.string() + ": " + e.what());
    }
    return;
  }
  source.yarn_spacing = f.number_in(*t, key, "yarn_spacing", std::nullopt, 0.0, 0.02, "m", true);
  source.amplitude = f.number_in(*t, key, "amplitude", std::nullopt, 0.0, 2e-3, "m");
  const std::string shape = f.string(*t, key, "shape", std::string("sine"));
  if (shape != "sine" && shape != "yarn") f.fail(t->get("shape"), key + ".shape", "must be \"sine\" or \"yarn\", not \"" + shape + "\"");
  source.shape = shape == "sine" ? cloth::WeaveShape::Sine : cloth::WeaveShape::Yarn;
  profile = cloth::weave_profile(source.yarn_spacing, source.amplitude, source.shape);
}

// [surface]: the fabric's surface for tactile rendering (optional).
cloth::Surface parse_surface(const TomlFile& f, const toml::table& root) {
  cloth::Surface s;
  const toml::table* t = f.table(root, "", "surface", false);
  if (!t) return s;
  f.only_keys(*t, "surface", {"source", "miu", "mmd", "weft", "warp"});
  s.source = f.string(*t, "surface", "source");
  s.miu = f.number_in(*t, "surface", "miu", 0.0, 0.0, 2.0, "");
  s.mmd = f.number_in(*t, "surface", "mmd", 0.0, 0.0, 1.0, "");
  parse_profile(f, *t, "weft", s.weft, s.weft_source);
  parse_profile(f, *t, "warp", s.warp, s.warp_source);
  if (!s.present()) f.fail(t, "surface", "needs [surface.weft] or [surface.warp]");
  s.normalize_friction();
  return s;
}

}  // namespace

cloth::Material parse_material(const TomlFile& f) {
  const toml::table& r = f.root();
  f.only_keys(r, "", {"name", "areal_density", "source", "weft", "warp", "shear", "surface"});
  cloth::Material m;
  m.name = f.string(r, "", "name", std::string("unnamed"));
  m.areal_density = f.number(r, "", "areal_density");
  if (!(m.areal_density > 0.0))
    f.fail(r.get("areal_density"), "areal_density", "must be > 0 (kg/m^2)");
  m.weft = parse_curve(f, r, "weft", false);
  m.warp = parse_curve(f, r, "warp", false);
  m.shear = parse_curve(f, r, "shear", true);
  m.surface = parse_surface(f, r);
  return m;
}

cloth::Material load_material(const std::string& path) {
  return parse_material(TomlFile::load(path));
}

std::string format_material(const cloth::Material& m, const std::string& comment) {
  std::ostringstream os;
  os << std::setprecision(10);
  if (!comment.empty()) {
    std::istringstream in(comment);
    std::string line;
    while (std::getline(in, line)) os << "# " << line << "\n";
  }
  os << "name = \"" << m.name << "\"\n";
  os << "areal_density = " << m.areal_density << "  # kg/m^2\n";
  auto curve = [&](const char* key, const cloth::StrainStressCurve& c) {
    os << "\n[" << key << "]  # N/m\n";
    os << "knots = [";
    for (int i = 0; i < c.segments; ++i) os << (i ? ", " : "") << c.knots[i];
    os << "]\nB = [";
    for (int i = 0; i < c.segments; ++i) {
      os << (i ? ", " : "") << "[";
      for (int j = 0; j < 4; ++j) os << (j ? ", " : "") << c.B[i][j];
      os << "]";
    }
    os << "]\n";
    if (c.viscosity > 0.0) os << "viscosity = " << c.viscosity << "  # N s/m\n";
    if (!c.odd && c.compression_scale != 1.0) os << "compression_scale = " << c.compression_scale << "\n";
  };
  curve("weft", m.weft);
  curve("warp", m.warp);
  curve("shear", m.shear);
  const cloth::Surface& s = m.surface;
  if (s.present()) {
    os << "\n[surface]\nsource = \"" << s.source << "\"\nmiu = " << s.miu << "\nmmd = " << s.mmd << "\n";
    auto profile = [&](const char* key, const cloth::SurfaceProfile& p, const cloth::SurfaceSource& src) {
      if (p.empty()) return;
      os << "\n[surface." << key << "]\n";
      if (!src.trace.empty())
        os << "trace = \"" << src.trace << "\"\n";
      else
        os << "yarn_spacing = " << src.yarn_spacing << "  # m\namplitude = " << src.amplitude
           << "  # m\nshape = \"" << cloth::to_string(src.shape) << "\"\n";
    };
    profile("weft", s.weft, s.weft_source);
    profile("warp", s.warp, s.warp_source);
  }
  return os.str();
}

}  // namespace hapticloth::app
