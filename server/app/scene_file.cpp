#include "app/scene_file.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <set>

#include <Eigen/LU>
#include <sstream>

#include "app/material_file.hpp"
#include "app/mesh_budget.hpp"
#include "app/obj_file.hpp"
#include "app/toml_file.hpp"
#include "registry.hpp"

namespace hapticloth::app {

namespace fs = std::filesystem;

namespace {

// Ranges of what a scene's values can mean: a cloth and a device on a bench.
constexpr int kMaxPcgIterations = 100000;  // a step of 10^5 iterations takes seconds at 16k triangles
constexpr double kMaxClothSize = 100.0;    // m across
constexpr double kMinElement = 1e-5;       // m, an element edge (0.01 mm: under that, rounding)
constexpr double kMaxCoordinate = 1e3;     // m, positions of the scene
constexpr double kMaxWorkspace = 10.0;     // m, a device's reach from its origin
constexpr double kMaxDeviceForce = 100.0;  // N: above every haptic device (tens of N)

std::string resolve(const std::string& scene_path, const std::string& rel) {
  fs::path p(rel);
  if (p.is_absolute()) return p.string();
  return (fs::path(scene_path).parent_path() / p).lexically_normal().string();
}

cloth::Mesh grid_mesh(const TomlFile& f, const toml::table& t) {
  f.only_keys(t, "mesh", {"type", "size", "resolution", "plane", "origin", "weave_angle_deg",
                          "diagonals"});
  cloth::GridSpec g;
  const auto size = f.numbers(t, "mesh", "size", 2, 2);
  if (!(size[0] > 0 && size[1] > 0 && size[0] <= kMaxClothSize && size[1] <= kMaxClothSize))
    f.fail(t.get("size"), "mesh.size", "must be > 0 and <= 100 m on each side");
  g.width = size[0];
  g.height = size[1];
  const auto res = f.numbers(t, "mesh", "resolution", 2, 2);
  for (double r : res)
    if (r < 1 || r > 1e6 || r != std::floor(r))
      f.fail(t.get("resolution"), "mesh.resolution", "must be two positive integers (quads per side)");
  g.nx = static_cast<int>(res[0]);
  g.ny = static_cast<int>(res[1]);
  if (std::min(g.width / g.nx, g.height / g.ny) < kMinElement)
    f.fail(t.get("resolution"), "mesh.resolution", "makes elements under 0.01 mm (mesh.size / resolution)");
  if (const std::string e = memory_limit_error(2L * g.nx * g.ny); !e.empty())
    f.fail(t.get("resolution"), "mesh.resolution", e);
  const std::string plane = f.string(t, "mesh", "plane", std::string("xy"));
  if (plane == "xy") g.plane = cloth::GridPlane::XY;
  else if (plane == "xz") g.plane = cloth::GridPlane::XZ;
  else if (plane == "yz") g.plane = cloth::GridPlane::YZ;
  else f.fail(t.get("plane"), "mesh.plane", "must be \"xy\", \"xz\" or \"yz\"");
  if (t.get("origin")) {
    const auto o = f.numbers(t, "mesh", "origin", 3, 3);
    g.origin = {o[0], o[1], o[2]};
    if (g.origin.cwiseAbs().maxCoeff() > kMaxCoordinate)
      f.fail(t.get("origin"), "mesh.origin", "must be within 1000 m of the scene's origin");
  }
  g.weave_angle_deg = f.number(t, "mesh", "weave_angle_deg", 0.0);
  const std::string diag = f.string(t, "mesh", "diagonals", std::string("alternate"));
  if (diag != "alternate" && diag != "uniform")
    f.fail(t.get("diagonals"), "mesh.diagonals", "must be \"alternate\" or \"uniform\"");
  g.alternate_diagonals = diag == "alternate";
  return cloth::make_grid(g);
}

cloth::Mesh obj_mesh(const TomlFile& f, const toml::table& t) {
  f.only_keys(t, "mesh", {"type", "path", "scale", "weave", "uv_scale"});
  const std::string path = resolve(f.path(), f.string(t, "mesh", "path"));
  const double scale = f.number_in(t, "mesh", "scale", 1.0, 0.0, 1e3, "(model units to m)", true);
  const std::string weave = f.string(t, "mesh", "weave", std::string("uv-directions"));
  if (weave != "uv-directions" && weave != "uv-metric")
    f.fail(t.get("weave"), "mesh.weave", "must be \"uv-directions\" or \"uv-metric\"");
  const double uv_scale = f.number(t, "mesh", "uv_scale", 1.0);
  ObjMesh obj = load_obj(path);
  if (const std::string e = memory_limit_error(static_cast<long>(obj.triangles.size())); !e.empty())
    f.fail(t.get("path"), "mesh.path", path + ": " + e);
  cloth::Mesh m;
  for (const auto& p : obj.positions) m.positions.push_back(scale * p);
  for (size_t i = 0; i < obj.triangles.size(); ++i) {
    const auto& tri = obj.triangles[i];
    const auto& tc = obj.triangle_texcoords[i];
    const std::string where = path + ":" + std::to_string(obj.triangle_lines[i]) + ": face";
    if (tc[0] < 0 || tc[1] < 0 || tc[2] < 0)
      throw ConfigError(where + " has no texture coordinates; the weave directions come from them");
    const Eigen::Vector2d uv[3] = {obj.texcoords[tc[0]], obj.texcoords[tc[1]], obj.texcoords[tc[2]]};
    std::array<std::array<double, 2>, 3> w;
    if (weave == "uv-metric") {
      for (int k = 0; k < 3; ++k) w[k] = {uv_scale * uv[k].x(), uv_scale * uv[k].y()};
    } else {
      // Direction of increasing texture u on the 3D triangle: dP/du.
      const Eigen::Vector3d p[3] = {m.positions[tri[0]], m.positions[tri[1]], m.positions[tri[2]]};
      const Eigen::Vector3d e1 = p[1] - p[0], e2 = p[2] - p[0];
      const Eigen::Vector2d d1 = uv[1] - uv[0], d2 = uv[2] - uv[0];
      const double det = d1.x() * d2.y() - d2.x() * d1.y();
      if (std::abs(det) < 1e-14)
        throw ConfigError(where + " is degenerate in texture space");
      const Eigen::Vector3d dPdu = (e1 * d2.y() - e2 * d1.y()) / det;
      try {
        w = cloth::flatten_triangle(p, dPdu);
      } catch (const std::invalid_argument& e) {
        throw ConfigError(where + ": " + e.what());
      }
    }
    m.triangles.push_back(tri);
    m.weave_uv.push_back(w);
  }
  return m;
}

}  // namespace

namespace {

Eigen::Vector3d vec3(const TomlFile& f, const toml::table& t, const std::string& prefix,
                     const std::string& key, const Eigen::Vector3d& fallback) {
  if (!t.get(key)) return fallback;
  const auto v = f.numbers(t, prefix, key, 3, 3);
  return {v[0], v[1], v[2]};
}

// [[device.part]] of driver = "composite": one single-finger streaming rig per finger (part i
// gives finger i), each with its own endpoint and record.
void load_device_parts(const TomlFile& f, const toml::table& t, const std::string& path, Scene& s) {
  auto& d = s.device;
  const toml::node* n = t.get("part");
  const bool composite = d.driver == "composite";
  if (!n) {
    if (composite)
      f.fail(t.get("driver"), "device.driver", "\"composite\" needs its parts: a [[device.part]] table per finger");
    return;
  }
  if (!composite) f.fail(n, "device.part", "parts make a device of driver = \"composite\", not " + d.driver);
  const toml::array* parts = n->as_array();
  if (!parts || !parts->is_array_of_tables())
    f.fail(n, "device.part", "expected [[device.part]] tables, one per finger");
  if (parts->size() < static_cast<std::size_t>(devices::kMinFingers) || parts->size() > static_cast<std::size_t>(devices::kMaxFingers))
    f.fail(n, "device.part", "a composite device has " + std::to_string(devices::kMinFingers) + " to " +
                                 std::to_string(devices::kMaxFingers) + " parts, one finger each");
  if (t.contains("fingers") && d.fingers != static_cast<int>(parts->size()))
    f.fail(t.get("fingers"), "device.fingers", "must equal the number of [[device.part]] tables (" +
                                                   std::to_string(parts->size()) + ")");
  d.fingers = static_cast<int>(parts->size());
  for (std::size_t i = 0; i < parts->size(); ++i) {
    const toml::table& pt = *(*parts)[i].as_table();
    const std::string prefix = "device.part[" + std::to_string(i) + "]";
    f.only_keys(pt, prefix, {"driver", "udp_bind", "record"});
    devices::DeviceOptions p;
    p.driver = f.string(pt, prefix, "driver");
    if (!devices::driver_paces_loop(p.driver))
      f.fail(pt.get("driver"), prefix + ".driver", "must be a one-finger rig that streams its samples (\"udp\"), not '" +
                                                      p.driver + "'");
    p.udp_bind = f.string(pt, prefix, "udp_bind");
    if (pt.get("record")) p.record_path = resolve(path, f.string(pt, prefix, "record"));
    d.parts.push_back(p);
  }
}

// [device.tactile]: the device's tactile display per fingertip (hal/tactile.hpp). Absent: none.
void load_device_tactile(const TomlFile& f, const toml::table& t, devices::DeviceOptions& d) {
  const toml::table* tt = f.table(t, "device", "tactile", false);
  if (!tt) return;
  const std::string pre = "device.tactile";
  f.only_keys(*tt, pre, {"vibration_rate", "pins", "pin_pitch", "max_vibration", "max_pin"});
  auto& c = d.tactile;
  c.vibration_rate = static_cast<int>(f.integer(*tt, pre, "vibration_rate", 0, 0,
                                                static_cast<long long>(devices::kMaxTactileSamples * 1000)));
  if (tt->get("pins")) {
    const std::vector<double> rc = f.numbers(*tt, pre, "pins", 2, 2);
    if (rc[0] != std::floor(rc[0]) || rc[1] != std::floor(rc[1]) || rc[0] < 1 || rc[1] < 1 ||
        rc[0] * rc[1] > devices::kMaxPins)
      f.fail(tt->get("pins"), pre + ".pins", "expected [rows, columns], whole numbers >= 1 with rows x columns <= " +
                                                 std::to_string(devices::kMaxPins));
    c.pin_rows = static_cast<int>(rc[0]);
    c.pin_cols = static_cast<int>(rc[1]);
  }
  c.pin_pitch = f.number_in(*tt, pre, "pin_pitch", c.pin_pitch, 0.0, 0.05, "m", true);
  c.max_vibration = f.number_in(*tt, pre, "max_vibration", c.max_vibration, 0.0, 0.01, "m", true);
  c.max_pin = f.number_in(*tt, pre, "max_pin", c.max_pin, 0.0, 0.01, "m", true);
  if (const std::string e = devices::validate(c, d.rate); !e.empty()) f.fail(tt, pre, e);
  if (c.vibration() == false && !c.pins())
    f.fail(tt, pre, "declares no vibration_rate and no pins: leave the table out for a device without a tactile display");
}

void load_device(const TomlFile& f, const toml::table& t, const std::string& path, Scene& s) {
  f.only_keys(t, "device", {"driver", "fingers", "workspace_min", "workspace_max", "max_force",
                            "max_stiffness", "rate", "script", "record", "replay", "udp_bind",
                            "clock", "origin", "axes", "part", "tactile"});
  auto& d = s.device;
  s.has_device = true;
  d.driver = f.string(t, "device", "driver");
  const auto known = devices::device_names();
  if (std::find(known.begin(), known.end(), d.driver) == known.end()) {
    std::string list;
    for (const auto& n : known) list += (list.empty() ? "" : ", ") + n;
    f.fail(t.get("driver"), "device.driver", "unknown driver '" + d.driver + "' (" + list + ")");
  }
  d.fingers = static_cast<int>(
      f.integer(t, "device", "fingers", d.fingers, devices::kMinFingers, devices::kMaxFingers));
  load_device_parts(f, t, path, s);
  d.workspace.min = vec3(f, t, "device", "workspace_min", d.workspace.min);
  d.workspace.max = vec3(f, t, "device", "workspace_max", d.workspace.max);
  for (const char* key : {"workspace_min", "workspace_max"}) {
    const Eigen::Vector3d& w = std::string(key) == "workspace_min" ? d.workspace.min : d.workspace.max;
    if (w.cwiseAbs().maxCoeff() > kMaxWorkspace)
      f.fail(t.get(key), std::string("device.") + key, "must be within 10 m of the device's origin (m)");
  }
  if (!(d.workspace.max.array() > d.workspace.min.array()).all())
    f.fail(t.get("workspace_max"), "device.workspace_max", "must exceed workspace_min on every axis");
  d.max_force = f.number_in(t, "device", "max_force", d.max_force, 0.0, kMaxDeviceForce, "N", true);
  d.max_stiffness = f.number_in(t, "device", "max_stiffness", d.max_stiffness, 0.0, 1e6, "N/m", true);
  d.rate = f.number_in(t, "device", "rate", d.rate, 1.0, 1e5, "Hz");
  load_device_tactile(f, t, d);
  if (t.get("script")) d.script = resolve(path, f.string(t, "device", "script"));
  if (t.get("record")) d.record_path = resolve(path, f.string(t, "device", "record"));
  if (t.get("replay")) d.replay_path = resolve(path, f.string(t, "device", "replay"));
  d.udp_bind = f.string(t, "device", "udp_bind", d.udp_bind);
  const std::string clock = f.string(t, "device", "clock", "loop");
  if (clock != "loop" && clock != "device")
    f.fail(t.get("clock"), "device.clock", "must be \"loop\" (the haptic loop's own deadlines) or "
                                           "\"device\" (a tick on each of the device's samples)");
  s.haptics.device_clock = clock == "device";
  if (s.haptics.device_clock && !devices::driver_paces_loop(d.driver))
    f.fail(t.get("clock"), "device.clock", "\"device\" needs a device that streams on its own "
                                           "clock (driver udp), not " + d.driver);
  auto& m = s.haptics.mapping;
  m.origin = vec3(f, t, "device", "origin", m.origin);
  if (const toml::node* ax = t.get("axes")) {
    const toml::array* rows = ax->as_array();
    if (!rows || rows->size() != 3) f.fail(ax, "device.axes", "expected 3 rows [x, y, z]: the scene directions of the device axes");
    Eigen::Matrix3d R;
    for (int c = 0; c < 3; ++c) {
      const toml::array* row = (*rows)[c].as_array();
      if (!row || row->size() != 3) f.fail(ax, "device.axes", "each row must be [x, y, z]");
      for (int k = 0; k < 3; ++k) {
        const auto v = (*row)[k].value<double>();
        if (!v) f.fail(ax, "device.axes", "expected numbers");
        R(k, c) = *v;  // column c: scene direction of device axis c
      }
    }
    if (!(R.transpose() * R).isIdentity(1e-6) || R.determinant() < 0.0)
      f.fail(ax, "device.axes", "must be a rotation (orthonormal rows, right-handed)");
    m.R = R;
  }
}

// A key that has a new name: read under either, never both; the old one adds a note naming the
// new one. Returns the value, or `fallback` when neither is there.
std::string renamed_string(const TomlFile& f, const toml::table& t, const char* now, const char* old,
                           const std::string& fallback) {
  if (t.contains(now) && t.contains(old))
    f.fail(t.get(old), std::string("haptics.") + old,
           std::string("is the old name of haptics.") + now + "; give only " + now);
  if (!t.contains(old)) return f.string(t, "haptics", now, fallback);
  return f.string(t, "haptics", old, fallback);
}

// haptics.rendering ("auto", "direct", "multirate") and haptics.multirate_model ("response",
// "patch"); their old names local_patch ("auto", "off", "on") and local_model are still read.
void load_rendering(const TomlFile& f, const toml::table& t, Scene& s) {
  const bool old_rendering = t.contains("local_patch");
  std::string r = renamed_string(f, t, "rendering", "local_patch", s.rendering);
  if (old_rendering) {
    if (r != "auto" && r != "on" && r != "off")
      f.fail(t.get("local_patch"), "haptics.local_patch", "must be \"auto\", \"on\" or \"off\" "
             "(its new name: rendering = \"auto\", \"multirate\" or \"direct\")");
    const std::string now = r == "on" ? "multirate" : r == "off" ? "direct" : "auto";
    s.notes.push_back(f.path() + ":" + std::to_string(t.get("local_patch")->source().begin.line) +
                      ": haptics.local_patch is now haptics.rendering: local_patch = \"" + r +
                      "\" read as rendering = \"" + now + "\"");
    r = now;
  } else if (r != "auto" && r != "direct" && r != "multirate") {
    f.fail(t.get("rendering"), "haptics.rendering", "must be \"auto\", \"direct\" or \"multirate\"");
  }
  s.rendering = r;
  const bool old_model = t.contains("local_model");
  const std::string model = renamed_string(f, t, "multirate_model", "local_model",
                                           haptics::to_string(s.multirate_model));
  const char* key = old_model ? "local_model" : "multirate_model";
  if (model == "response") s.multirate_model = haptics::LocalModel::Response;
  else if (model == "patch") s.multirate_model = haptics::LocalModel::Patch;
  else f.fail(t.get(key), std::string("haptics.") + key, "must be \"response\" or \"patch\"");
  if (old_model)
    s.notes.push_back(f.path() + ":" + std::to_string(t.get("local_model")->source().begin.line) +
                      ": haptics.local_model is now haptics.multirate_model");
}

void load_haptics(const TomlFile& f, const toml::table& t, Scene& s) {
  f.only_keys(t, "haptics", {"rate", "finger_radius", "stiffness", "damping", "friction",
                             "kernel_radius", "margin", "preroll", "slew_rate", "watchdog_ms",
                             "ramp_ms", "max_force", "realtime", "rendering", "multirate_model",
                             "local_patch", "local_model", "finger_mass", "contact_stiffness", "refine"});
  auto& h = s.haptics;
  // Each value in the range a fingertip on a bench can mean; `positive` ranges are open at 0.
  auto positive = [&](const char* key, double& v, double hi, const char* unit) {
    v = f.number_in(t, "haptics", key, v, 0.0, hi, unit, true);
  };
  auto in = [&](const char* key, double& v, double lo, double hi, const char* unit) {
    v = f.number_in(t, "haptics", key, v, lo, hi, unit);
  };
  // A haptic loop under 100 Hz renders steps the hand feels; over 10 kHz the period is within
  // this platform's timer jitter (BENCHMARKS.md, 'Real time beside the platform's timer').
  in("rate", h.haptic_rate, 100.0, 10000.0, "Hz");
  in("finger_radius", h.finger.radius, 1e-3, 0.05, "m (a fingertip or a stylus tip)");
  positive("stiffness", h.finger.stiffness, 1e6, "N/m");
  in("damping", h.finger.damping, 0.0, 1e3, "N s/m");
  in("friction", h.finger.friction, 0.0, 10.0, "(Coulomb coefficient)");
  in("kernel_radius", h.coupling.kernel_radius, 0.0, 0.1, "m; 0 = automatic");
  in("margin", h.coupling.margin, 0.0, 0.1, "m");
  in("finger_mass", h.coupling.finger_mass, 0.0, 1.0, "kg; 0 = no impact transfer");
  positive("contact_stiffness", h.finger.contact_stiffness, 1e13, "Pa/m, contact pressure per metre of depth");
  in("preroll", s.preroll, 0.0, 600.0, "s");
  positive("slew_rate", h.gate.slew_rate, 1e6, "N/s");
  double wd = h.gate.watchdog * 1e3, ramp = h.gate.ramp_time * 1e3;
  positive("watchdog_ms", wd, 10000.0, "ms");
  positive("ramp_ms", ramp, 10000.0, "ms");
  h.gate.watchdog = wd * 1e-3;
  h.gate.ramp_time = ramp * 1e-3;
  in("max_force", h.gate.max_force, 0.0, kMaxDeviceForce, "N; 0 = the device's");
  h.try_realtime = f.boolean(t, "haptics", "realtime", h.try_realtime);
  load_rendering(f, t, s);
  const std::string refine = f.string(t, "haptics", "refine", haptics::to_string(h.coupling.refine));
  if (refine == "auto") h.coupling.refine = haptics::Refine::Auto;
  else if (refine == "on") h.coupling.refine = haptics::Refine::On;
  else if (refine == "off") h.coupling.refine = haptics::Refine::Off;
  else f.fail(t.get("refine"), "haptics.refine", "must be \"auto\", \"on\" or \"off\"");
  if (h.coupling.refine == haptics::Refine::On && s.rendering == "multirate" &&
      s.multirate_model == haptics::LocalModel::Patch)
    f.fail(t.get("refine"), "haptics.refine",
           "applies to direct coupling and to multirate_model = \"response\"; the patch model "
           "renders from its own subdivided patch");
  // Direct coupling and the response model solve the fingertip spheres with the cloth: no
  // kernel spreads the force and the contact itself exchanges the impact momentum.
  for (const char* key : {"kernel_radius", "finger_mass"}) {
    if (!t.contains(key)) continue;
    if (s.rendering == "direct")
      f.fail(t.get(key), std::string("haptics.") + key,
             "applies only to rendering = \"multirate\" with multirate_model = \"patch\"; with "
             "direct coupling the fingertip is a sphere solved with the cloth (its contact is set "
             "by contact_stiffness)");
    if (s.multirate_model != haptics::LocalModel::Patch)
      f.fail(t.get(key), std::string("haptics.") + key,
             "applies only to multirate_model = \"patch\"; the response model solves the "
             "fingertip sphere with the cloth (its contact is set by contact_stiffness)");
  }
}

// material = "file.toml": its errors are reported at the scene's key, naming the material file.
void load_scene_material(const TomlFile& f, const std::string& path, Scene& s) {
  const std::string name = f.string(f.root(), "", "material");
  if (name.empty()) f.fail(f.root().get("material"), "material", "must name a material file (TOML)");
  s.material_path = resolve(path, name);
  try {
    s.material = load_material(s.material_path);
  } catch (const ConfigError& e) {
    f.fail(f.root().get("material"), "material", e.what());
  }
}

void load_mesh(const TomlFile& f, Scene& s) {
  const toml::table* mt = f.table(f.root(), "", "mesh", true);
  const std::string type = f.string(*mt, "mesh", "type");
  if (type == "grid") s.mesh = grid_mesh(f, *mt);
  else if (type == "obj") s.mesh = obj_mesh(f, *mt);
  else f.fail(mt->get("type"), "mesh.type", "must be \"grid\" or \"obj\"");
}

// [pins]: the union of named grid edges, vertex indices and the vertices inside a box.
void load_pins(const TomlFile& f, const toml::table& pt, Scene& s) {
  f.only_keys(pt, "pins", {"edges", "vertices", "box_min", "box_max"});
  std::set<int> pins;
  for (const auto& e : f.strings(pt, "pins", "edges")) {
    try {
      for (int v : cloth::grid_edge(s.mesh, e)) pins.insert(v);
    } catch (const std::invalid_argument& err) {
      f.fail(pt.get("edges"), "pins.edges", err.what());
    }
  }
  if (pt.get("vertices")) {
    const int nv = static_cast<int>(s.mesh.positions.size());
    for (double v : f.numbers(pt, "pins", "vertices", 0, 1u << 30)) {
      if (v != std::floor(v) || v < 0 || v >= nv) {
        std::ostringstream os;
        os << "vertex " << v << " is not an index in [0, " << nv << ")";
        f.fail(pt.get("vertices"), "pins.vertices", os.str());
      }
      pins.insert(static_cast<int>(v));
    }
  }
  if (pt.get("box_min") || pt.get("box_max")) {
    const auto lo = f.numbers(pt, "pins", "box_min", 3, 3);
    const auto hi = f.numbers(pt, "pins", "box_max", 3, 3);
    for (int k = 0; k < 3; ++k)
      if (!(hi[k] >= lo[k]))
        f.fail(pt.get("box_max"), "pins.box_max", "must be >= box_min on every axis (x, y, z)");
    bool any = false;
    for (size_t i = 0; i < s.mesh.positions.size(); ++i) {
      const auto& p = s.mesh.positions[i];
      if (p.x() >= lo[0] && p.x() <= hi[0] && p.y() >= lo[1] && p.y() <= hi[1] &&
          p.z() >= lo[2] && p.z() <= hi[2]) {
        pins.insert(static_cast<int>(i));
        any = true;
      }
    }
    if (!any) f.fail(pt.get("box_min"), "pins.box_min", "the box [box_min, box_max] holds no vertex of the mesh");
  }
  s.pins.assign(pins.begin(), pins.end());
}

void load_physics(const TomlFile& f, const toml::table& ph, Scene& s) {
  f.only_keys(ph, "physics", {"gravity", "air_damping"});
  if (ph.get("gravity")) {
    const auto g = f.numbers(ph, "physics", "gravity", 3, 3);
    s.integrator.gravity = {g[0], g[1], g[2]};
    if (s.integrator.gravity.norm() > 1e3)
      f.fail(ph.get("gravity"), "physics.gravity", "must be at most 1000 m/s^2 (100 g)");
  }
  s.integrator.air_damping = f.number_in(ph, "physics", "air_damping", 0.0, 0.0, 1e4, "N s/m^3");
}

void load_integrator(const TomlFile& f, const toml::table& it, Scene& s) {
  f.only_keys(it, "integrator", {"dt", "alpha", "solver", "jacobian", "pcg_tolerance",
                                 "pcg_max_iterations", "pcg_float_matrix", "pcg_preconditioner", "pcg_ssor_omega",
                                 "max_halvings",
                                 "explosion_ratio", "threads", "matrix_refresh"});
  auto& c = s.integrator;
  c.dt = f.number_in(it, "integrator", "dt", c.dt, kMinDt, kMaxDt, "s");
  c.alpha = f.number(it, "integrator", "alpha", c.alpha);
  if (!(c.alpha >= 0.5 && c.alpha <= 1.0))
    f.fail(it.get("alpha"), "integrator.alpha", "must be in [0.5, 1] (eq. 8)");
  s.solver = f.string(it, "integrator", "solver", s.solver);
  if (std::find(kSolvers.begin(), kSolvers.end(), s.solver) == kSolvers.end())
    f.fail(it.get("solver"), "integrator.solver", "must be \"pcg\", \"cholmod\" or \"cholmod-supernodal\"");
  const std::string jac = f.string(it, "integrator", "jacobian", std::string("spd"));
  if (jac == "spd") c.jacobian = cloth::JacobianMode::Spd;
  else if (jac == "exact") c.jacobian = cloth::JacobianMode::Exact;
  else f.fail(it.get("jacobian"), "integrator.jacobian", "must be \"spd\" or \"exact\"");
  s.pcg.tolerance = f.number(it, "integrator", "pcg_tolerance", s.pcg.tolerance);
  if (!(s.pcg.tolerance > 0.0 && s.pcg.tolerance < 1.0))
    f.fail(it.get("pcg_tolerance"), "integrator.pcg_tolerance", "must be in (0, 1)");
  s.pcg.max_iterations = static_cast<int>(
      f.integer(it, "integrator", "pcg_max_iterations", s.pcg.max_iterations, 1, kMaxPcgIterations));
  s.pcg.single_precision_matrix =
      f.boolean(it, "integrator", "pcg_float_matrix", s.pcg.single_precision_matrix);
  const std::string pre =
      f.string(it, "integrator", "pcg_preconditioner", std::string(cloth::to_string(s.pcg.preconditioner)));
  if (pre == "ssor") s.pcg.preconditioner = cloth::PcgPreconditioner::Ssor;
  else if (pre == "block-jacobi") s.pcg.preconditioner = cloth::PcgPreconditioner::BlockJacobi;
  else f.fail(it.get("pcg_preconditioner"), "integrator.pcg_preconditioner", "must be \"ssor\" or \"block-jacobi\"");
  s.pcg.ssor_omega = f.number(it, "integrator", "pcg_ssor_omega", s.pcg.ssor_omega);
  if (!(s.pcg.ssor_omega >= 1.0 && s.pcg.ssor_omega < 2.0))
    f.fail(it.get("pcg_ssor_omega"), "integrator.pcg_ssor_omega", "must be in [1, 2) (SSOR's relaxation factor)");
  c.max_halvings = static_cast<int>(f.integer(it, "integrator", "max_halvings", c.max_halvings, 0, 20));
  c.explosion_ratio = f.number_in(it, "integrator", "explosion_ratio", c.explosion_ratio, 0.0, 1e6, "", true);
  c.assembly_threads = static_cast<int>(f.integer(it, "integrator", "threads", c.assembly_threads, 1, 2));
  c.matrix_refresh = f.number(it, "integrator", "matrix_refresh", c.matrix_refresh);
  if (!(c.matrix_refresh >= 0.0 && c.matrix_refresh < 1.0))
    f.fail(it.get("matrix_refresh"), "integrator.matrix_refresh",
           "must be in [0, 1) (an element's change that forms its blocks anew; 0: every step)");
}

}  // namespace

Scene load_scene(const std::string& path) {
  const TomlFile f = TomlFile::load(path);
  const toml::table& r = f.root();
  f.only_keys(r, "", {"name", "material", "duration", "mesh", "pins", "physics", "integrator",
                      "device", "haptics"});
  Scene s;
  s.path = path;
  s.name = f.string(r, "", "name", fs::path(path).stem().string());
  // The name is a file name (out/<name>.lcm): one that stays in out/.
  const bool control = std::any_of(s.name.begin(), s.name.end(),
                                   [](char c) { return std::iscntrl(static_cast<unsigned char>(c)); });
  if (s.name.empty() || s.name[0] == '.' || s.name.find_first_of("/\\") != std::string::npos || control)
    f.fail(r.get("name"), "name", "'" + s.name + "' must be a file name: not empty, without / or \\ or "
                                  "control characters, not starting with '.' (it names out/<name>.lcm)");
  s.duration = f.number_in(r, "", "duration", 10.0, 0.0, 1e6, "s", true);
  load_scene_material(f, path, s);
  load_mesh(f, s);
  if (const toml::table* t = f.table(r, "", "pins", false)) load_pins(f, *t, s);
  if (const toml::table* t = f.table(r, "", "physics", false)) load_physics(f, *t, s);
  if (const toml::table* t = f.table(r, "", "integrator", false)) load_integrator(f, *t, s);
  if (const toml::table* t = f.table(r, "", "device", false)) load_device(f, *t, path, s);
  if (const toml::table* t = f.table(r, "", "haptics", false)) load_haptics(f, *t, s);
  s.device.stale_after = s.haptics.gate.watchdog;  // a sample the watchdog would call stale
  s.device.stale_ramp = s.haptics.gate.ramp_time;
  return s;
}

cloth::ClothModel build_model(const Scene& s) {
  try {
    return cloth::build_model(s.mesh, s.material, s.pins);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(s.path + ": " + e.what());
  }
}

std::unique_ptr<cloth::Integrator> make_integrator(const Scene& s, const cloth::ClothModel& m) {
  return std::make_unique<cloth::Integrator>(m, s.integrator, cloth::make_solver(s.solver, s.pcg));
}

}  // namespace hapticloth::app
