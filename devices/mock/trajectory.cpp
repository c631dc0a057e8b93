#include "mock/trajectory.hpp"
#include "log/input_file.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <initializer_list>
#include <sstream>
#include <stdexcept>

#include <toml++/toml.h>

#include "log/device_log.hpp"

namespace hapticloth::devices {

void Trajectory::add(int finger, double t, const Vec3& p) {
  if (finger < 0 || finger >= fingers()) throw std::invalid_argument("finger index out of range");
  if (!std::isfinite(t) || !p.allFinite()) throw std::invalid_argument("non-finite keyframe");
  auto& k = keys_[finger];
  if (!k.empty() && t < k.back().t) throw std::invalid_argument("keyframe times must not decrease");
  k.push_back({t, p});
}

void Trajectory::sample(int fingers, double t, double now, DeviceState& s) const noexcept {
  for (int f = 0; f < fingers; ++f) evaluate(f, t, s.finger[f].position, s.finger[f].velocity);
  s.device_time = t;
  s.received_time = now;
  ++s.sequence;
}

void Trajectory::evaluate(int finger, double t, Vec3& p, Vec3& v) const noexcept {
  v.setZero();
  if (finger < 0 || finger >= fingers() || keys_[finger].empty()) {
    p.setZero();
    return;
  }
  const auto& k = keys_[finger];
  if (!(t > k.front().t)) {
    p = k.front().p;
    return;
  }
  if (t >= k.back().t) {
    p = k.back().p;
    return;
  }
  const auto it = std::upper_bound(k.begin(), k.end(), t,
                                   [](double x, const Keyframe& f) { return x < f.t; });
  const Keyframe& b = *it;
  const Keyframe& a = *(it - 1);
  const double dt = b.t - a.t;
  if (dt <= 0.0) {
    p = b.p;
    return;
  }
  const double s = (t - a.t) / dt;
  p = a.p + s * (b.p - a.p);
  v = (b.p - a.p) / dt;
}

double Trajectory::duration() const {
  double d = 0.0;
  for (const auto& k : keys_)
    if (!k.empty()) d = std::max(d, k.back().t);
  return d;
}

void Trajectory::check_inside(const Box& b, const std::string& source) const {
  for (int f = 0; f < fingers(); ++f) {
    if (keys_[f].empty())
      throw std::invalid_argument(source + ": no keyframes for finger " + std::to_string(f));
    for (const auto& k : keys_[f]) {
      if (!b.contains(k.p)) {
        std::ostringstream os;
        os << source << ": finger " << f << " at t = " << k.t << " s is at (" << k.p.transpose()
           << ") m, outside the device workspace (" << b.min.transpose() << ") .. ("
           << b.max.transpose() << ")";
        throw std::invalid_argument(os.str());
      }
    }
  }
}

void Trajectory::check_speed(double max_speed, const std::string& source) const {
  for (int f = 0; f < fingers(); ++f) {
    const auto& k = keys_[f];
    for (size_t i = 1; i < k.size(); ++i) {
      const double d = (k[i].p - k[i - 1].p).norm(), dt = k[i].t - k[i - 1].t;
      if (d > max_speed * dt) {
        std::ostringstream os;
        os << source << ": finger " << f << " moves " << d * 1e3 << " mm in " << dt
           << " s between t = " << k[i - 1].t << " and " << k[i].t << " s (" << (dt > 0 ? d / dt : INFINITY)
           << " m/s), faster than " << max_speed << " m/s (kMaxScriptSpeed: a hand moves at up to about 2 m/s)";
        throw std::invalid_argument(os.str());
      }
    }
  }
}

Trajectory load_trajectory_csv(const std::string& path, int fingers) {
  if (std::string e = check_input_file(path, kMaxDataBytes); !e.empty()) throw std::invalid_argument(e);
  std::ifstream in(path);
  if (!in) throw std::invalid_argument(path + ": cannot open the trajectory");
  Trajectory tr(fingers);
  std::string line;
  int ln = 0, ct = -1, cf = -1, cx = -1, cy = -1, cz = -1;
  bool header = false;
  while (std::getline(in, line)) {
    ++ln;
    if (line.find_first_not_of(" \t\r") == std::string::npos || line[0] == '#') continue;
    const auto c = split_csv(line);
    const std::string where = path + ":" + std::to_string(ln) + ": ";
    if (!header) {
      for (int i = 0; i < static_cast<int>(c.size()); ++i) {
        if (c[i] == "time") ct = i;
        if (c[i] == "finger") cf = i;
        if (c[i] == "x") cx = i;
        if (c[i] == "y") cy = i;
        if (c[i] == "z") cz = i;
      }
      if (ct < 0 || cf < 0 || cx < 0 || cy < 0 || cz < 0)
        throw std::invalid_argument(where + "expected the header 'time,finger,x,y,z'");
      header = true;
      continue;
    }
    const int need = std::max({ct, cf, cx, cy, cz}) + 1;
    if (static_cast<int>(c.size()) < need)
      throw std::invalid_argument(where + "expected " + std::to_string(need) + " columns");
    const double t = parse_number(c[ct], path, ln, "time");
    const double f = parse_number(c[cf], path, ln, "finger");
    if (f < 0 || f >= fingers || f != std::floor(f))
      throw std::invalid_argument(where + "finger must be an integer in 0.." + std::to_string(fingers - 1));
    const Vec3 p(parse_number(c[cx], path, ln, "x"), parse_number(c[cy], path, ln, "y"),
                 parse_number(c[cz], path, ln, "z"));
    const auto& k = tr.keys(static_cast<int>(f));
    if (!k.empty() && t < k.back().t)
      throw std::invalid_argument(where + "time goes backwards for finger " + std::to_string(static_cast<int>(f)));
    if (!k.empty() && (p - k.back().p).norm() > kMaxScriptSpeed * (t - k.back().t)) {
      std::ostringstream os;
      os << where << "finger " << static_cast<int>(f) << " moves " << (p - k.back().p).norm() * 1e3
         << " mm in " << t - k.back().t << " s, faster than " << kMaxScriptSpeed << " m/s";
      throw std::invalid_argument(os.str());
    }
    tr.add(static_cast<int>(f), t, p);
  }
  if (!header) throw std::invalid_argument(path + ": empty trajectory (no header)");
  for (int f = 0; f < fingers; ++f)
    if (tr.keys(f).empty())
      throw std::invalid_argument(path + ": no rows for finger " + std::to_string(f));
  return tr;
}

namespace {

// Primitive script builder: every step moves all fingers from where they are, linearly.
struct Builder {
  Trajectory tr;
  std::vector<Vec3> at;
  double t = 0.0;
  explicit Builder(const std::vector<Vec3>& start) : tr(static_cast<int>(start.size())), at(start) {
    for (int f = 0; f < tr.fingers(); ++f) tr.add(f, 0.0, at[f]);
  }
  void to(const std::vector<Vec3>& target, double duration) {
    t += duration;
    at = target;
    for (int f = 0; f < tr.fingers(); ++f) tr.add(f, t, at[f]);
  }
  Vec3 centre() const {
    Vec3 c = Vec3::Zero();
    for (const auto& p : at) c += p;
    return c / static_cast<double>(at.size());
  }
  // Fingers 0 and 1 move along the line between them so that their centres are `gap` apart
  // (the others move with the centre of the pair).
  void set_gap(double gap, double duration) {
    std::vector<Vec3> n = at;
    Vec3 d = at[1] - at[0];
    const double len = d.norm();
    d = len > 1e-12 ? Vec3(d / len) : Vec3(1, 0, 0);
    const Vec3 mid = 0.5 * (at[0] + at[1]);
    n[0] = mid - 0.5 * gap * d;
    n[1] = mid + 0.5 * gap * d;
    to(n, duration);
  }
  void shift(const Vec3& delta, double duration) {
    std::vector<Vec3> n = at;
    for (auto& p : n) p += delta;
    to(n, duration);
  }
};

// A parsed trajectory script and its typed reads; every error is a std::invalid_argument
// "PATH:LINE: key 'step[2].depth': message", as a scene file's are (devices/ does not depend on
// server/, so it has its own reader).
struct Script {
  std::string path;
  toml::table root;

  [[noreturn]] void fail(const toml::node* n, const std::string& key, const std::string& msg) const {
    std::ostringstream os;
    os << path;
    if (n && n->source().begin.line) os << ":" << n->source().begin.line;
    os << ": key '" << key << "': " << msg;
    throw std::invalid_argument(os.str());
  }

  Vec3 vec3(const toml::node* n, const std::string& key) const {
    const toml::array* a = n ? n->as_array() : nullptr;
    if (!a || a->size() != 3) fail(n, key, "expected [x, y, z] in metres");
    Vec3 v;
    for (int i = 0; i < 3; ++i) {
      const auto x = (*a)[i].value<double>();
      if (!x || !std::isfinite(*x)) fail(n, key, "expected three finite numbers");
      v[i] = *x;
    }
    return v;
  }

  // t[key] (named prefix.key in messages), or `dflt` when absent.
  double number(const toml::table& t, const std::string& prefix, const char* key, double dflt,
                bool positive) const {
    const toml::node* n = t.get(key);
    if (!n) return dflt;
    const auto x = n->value<double>();
    if (!x || !std::isfinite(*x)) fail(n, prefix + "." + key, "expected a finite number");
    if (positive && !(*x > 0.0)) fail(n, prefix + "." + key, "must be > 0");
    return *x;
  }
};

Script parse_script(const std::string& path) {
  Script s{path, {}};
  if (std::string e = check_input_file(path, kMaxConfigBytes); !e.empty()) throw std::invalid_argument(e);
  try {
    s.root = toml::parse_file(path);
  } catch (const toml::parse_error& e) {
    std::ostringstream os;
    os << path << ":" << e.source().begin.line << ": " << e.description();
    throw std::invalid_argument(os.str());
  }
  for (const auto& [k, v] : s.root)
    if (k != "start" && k != "step") s.fail(&v, std::string(k.str()), "unknown key (start, step)");
  return s;
}

// [start]: finger0 = [x, y, z], finger1 = ...
std::vector<Vec3> start_positions(const Script& s, int fingers) {
  const toml::table* start = s.root["start"].as_table();
  if (!start) s.fail(nullptr, "start", "missing table [start] with finger0 = [x, y, z], ...");
  std::vector<Vec3> p0;
  for (int f = 0; f < fingers; ++f) {
    const std::string key = "finger" + std::to_string(f);
    const toml::node* n = start->get(key);
    if (!n) s.fail(start, "start." + key, "missing");
    p0.push_back(s.vec3(n, "start." + key));
  }
  return p0;
}

// Rejects a key of the step that is not a parameter of its primitive `p`.
void only_parameters(const Script& s, const toml::table& st, const std::string& pre,
                     const std::string& p, std::initializer_list<const char*> keys) {
  for (const auto& [k, v] : st) {
    bool ok = k == "primitive" || k == "duration";
    for (const char* a : keys) ok = ok || k == a;
    if (!ok) s.fail(&v, pre + "." + std::string(k.str()), "not a parameter of '" + p + "'");
  }
}

// "move": absolute positions, fingerN = [x, y, z]; the fingers not named stay.
std::vector<Vec3> move_targets(const Script& s, const toml::table& st, const std::string& pre,
                               const std::vector<Vec3>& at) {
  std::vector<Vec3> n = at;
  const int fingers = static_cast<int>(at.size());
  for (const auto& [k, v] : st) {
    if (k == "primitive" || k == "duration") continue;
    const std::string ks(k.str());
    int f = -1;
    if (ks.rfind("finger", 0) == 0) f = std::atoi(ks.c_str() + 6);
    if (f < 0 || f >= fingers || ks != "finger" + std::to_string(f))
      s.fail(&v, pre + "." + ks, "not a parameter of 'move' (finger0, finger1, ...)");
    n[f] = s.vec3(&v, pre + "." + ks);
  }
  return n;
}

// One [[step]]: its primitive, with its parameters, appended to the builder.
void add_step(const Script& s, const toml::node& node, const std::string& pre, Builder& b) {
  const toml::table* st = node.as_table();
  if (!st) s.fail(&node, pre, "expected a table");
  const auto prim = (*st)["primitive"].value<std::string>();
  if (!prim) s.fail(st, pre + ".primitive", "missing (approach, press, stroke, pinch, lift, release, hold, move)");
  const double dur = s.number(*st, pre, "duration", 0.5, true);
  const std::string& p = *prim;
  auto allowed = [&](std::initializer_list<const char*> keys) { only_parameters(s, *st, pre, p, keys); };
  if (p == "approach") {  // down by distance (default 2 cm)
    allowed({"distance"});
    b.shift(Vec3(0, 0, -s.number(*st, pre, "distance", 0.02, true)), dur);
  } else if (p == "press") {  // down by depth (default 5 mm)
    allowed({"depth"});
    b.shift(Vec3(0, 0, -s.number(*st, pre, "depth", 0.005, true)), dur);
  } else if (p == "lift") {  // up by height (default 1 cm)
    allowed({"height"});
    b.shift(Vec3(0, 0, s.number(*st, pre, "height", 0.01, true)), dur);
  } else if (p == "stroke") {  // along direction by distance (default 3 cm along x)
    allowed({"distance", "direction"});
    Vec3 d(1, 0, 0);
    if (const toml::node* n = st->get("direction")) d = s.vec3(n, pre + ".direction");
    if (!(d.norm() > 0.0)) s.fail(st->get("direction"), pre + ".direction", "must not be zero");
    b.shift(s.number(*st, pre, "distance", 0.03, true) * d.normalized(), dur);
  } else if (p == "pinch") {  // fingers 0, 1 close to gap between centres (default 16 mm)
    allowed({"gap"});
    b.set_gap(s.number(*st, pre, "gap", 0.016, true), dur);
  } else if (p == "release") {  // fingers 0, 1 open to gap (default 4 cm)
    allowed({"gap"});
    b.set_gap(s.number(*st, pre, "gap", 0.04, true), dur);
  } else if (p == "hold") {
    allowed({});
    b.shift(Vec3::Zero(), dur);
  } else if (p == "move") {
    b.to(move_targets(s, *st, pre, b.at), dur);
  } else {
    s.fail(st->get("primitive"), pre + ".primitive",
           "unknown primitive '" + p + "' (approach, press, stroke, pinch, lift, release, hold, move)");
  }
}

}  // namespace

Trajectory load_trajectory_toml(const std::string& path, int fingers) {
  const Script s = parse_script(path);
  Builder b(start_positions(s, fingers));
  const toml::array* steps = s.root["step"].as_array();
  if (!steps || steps->empty()) s.fail(nullptr, "step", "missing: at least one [[step]]");
  for (size_t i = 0; i < steps->size(); ++i) add_step(s, (*steps)[i], "step[" + std::to_string(i) + "]", b);
  return b.tr;
}

Trajectory load_trajectory(const std::string& path, int fingers) {
  auto ends = [&](const char* s) {
    const std::string e(s);
    return path.size() >= e.size() && path.compare(path.size() - e.size(), e.size(), e) == 0;
  };
  if (ends(".csv")) return load_trajectory_csv(path, fingers);
  if (ends(".toml")) return load_trajectory_toml(path, fingers);
  throw std::invalid_argument(path + ": a trajectory is a .csv (time,finger,x,y,z) or .toml script");
}

Trajectory demo_trajectory(int fingers) {
  std::vector<Vec3> p0;
  for (int f = 0; f < fingers; ++f) p0.push_back(Vec3(-0.02 + 0.04 * f / std::max(1, fingers - 1), 0.0, 0.03));
  Builder b(p0);
  b.shift(Vec3::Zero(), 0.2);            // hold
  b.shift(Vec3(0, 0, -0.03), 0.6);       // approach to the cloth plane
  b.shift(Vec3(0, 0, -0.005), 0.4);      // press 5 mm
  b.shift(Vec3(0.03, 0, 0), 1.0);        // stroke 3 cm
  b.shift(Vec3(0, 0, 0.005), 0.3);       // back to the surface
  b.set_gap(0.016, 0.6);                 // pinch
  b.shift(Vec3(0, 0, 0.01), 0.6);        // lift 1 cm
  b.set_gap(0.04, 0.4);                  // release
  b.shift(Vec3(0, 0, 0.02), 0.5);        // away
  return b.tr;
}

}  // namespace hapticloth::devices
