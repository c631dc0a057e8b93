#include "app/material_file.hpp"

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

}  // namespace

cloth::Material parse_material(const TomlFile& f) {
  const toml::table& r = f.root();
  f.only_keys(r, "", {"name", "areal_density", "source", "weft", "warp", "shear"});
  cloth::Material m;
  m.name = f.string(r, "", "name", std::string("unnamed"));
  m.areal_density = f.number(r, "", "areal_density");
  if (!(m.areal_density > 0.0))
    f.fail(r.get("areal_density"), "areal_density", "must be > 0 (kg/m^2)");
  m.weft = parse_curve(f, r, "weft", false);
  m.warp = parse_curve(f, r, "warp", false);
  m.shear = parse_curve(f, r, "shear", true);
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
  return os.str();
}

}  // namespace hapticloth::app
