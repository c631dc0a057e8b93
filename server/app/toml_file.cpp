#include "app/toml_file.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <type_traits>

#include "log/input_file.hpp"
namespace hapticloth::app {

TomlFile TomlFile::load(const std::string& path) {
  std::string text;
  if (std::string e = devices::read_input_file(path, devices::kMaxConfigBytes, text); !e.empty())
    throw ConfigError(e);
  return parse(text, path);
}

TomlFile TomlFile::parse(const std::string& text, const std::string& name) {
  TomlFile f;
  f.path_ = name;
  try {
    f.root_ = toml::parse(text, name);
  } catch (const toml::parse_error& e) {
    std::ostringstream os;
    os << name << ":" << e.source().begin.line << ": invalid TOML: " << e.description();
    throw ConfigError(os.str());
  }
  return f;
}

void TomlFile::fail(const toml::node* at, const std::string& key, const std::string& what) const {
  std::ostringstream os;
  os << path_;
  if (at && at->source().begin.line > 0) os << ":" << at->source().begin.line;
  os << ": key '" << key << "': " << what;
  throw ConfigError(os.str());
}

const toml::node* TomlFile::find(const toml::table& t, const std::string& key) const {
  return t.get(key);
}

namespace {

// Whether a node holds a T (a number may be an integer or a float).
template <class T>
bool holds(const toml::node& n) {
  if constexpr (std::is_same_v<T, double>) return n.is_number();
  else if constexpr (std::is_same_v<T, long long>) return n.is_integer();
  else if constexpr (std::is_same_v<T, bool>) return n.is_boolean();
  else return n.is_string();
}

// t[key] as a T, or the fallback when absent; `what` names the type in messages ("a number").
template <class T>
T scalar(const TomlFile& f, const toml::table& t, const std::string& prefix, const std::string& key,
         const std::optional<T>& fallback, const std::string& what) {
  const toml::node* n = t.get(key);
  const std::string k = TomlFile::join(prefix, key);
  if (!n) {
    if (fallback) return *fallback;
    f.fail(&t, k, "missing (" + what + " is required)");
  }
  if (!holds<T>(*n)) f.fail(n, k, "expected " + what);
  return n->value<T>().value();
}

}  // namespace

double TomlFile::number(const toml::table& t, const std::string& prefix, const std::string& key,
                        std::optional<double> fallback) const {
  const double v = scalar<double>(*this, t, prefix, key, fallback, "a number");
  if (!std::isfinite(v)) fail(t.get(key), join(prefix, key), "must be finite");
  return v;
}

double TomlFile::number_in(const toml::table& t, const std::string& prefix, const std::string& key,
                           std::optional<double> fallback, double lo, double hi, const std::string& unit,
                           bool open_lo) const {
  const double v = number(t, prefix, key, fallback);
  if ((open_lo ? v <= lo : v < lo) || v > hi) {
    std::ostringstream os;
    os << "must be " << (open_lo ? "> " : ">= ") << lo << " and <= " << hi << (unit.empty() ? "" : " " + unit)
       << ", not " << v;
    fail(t.get(key), join(prefix, key), os.str());
  }
  return v;
}

long long TomlFile::integer(const toml::table& t, const std::string& prefix, const std::string& key,
                            std::optional<long long> fallback, long long lo, long long hi) const {
  // toml++ refuses integers past 2^63 itself (invalid TOML); in range of long long, the callers'
  // ints would wrap silently past 2^31, so every integer key has its range.
  const long long v = scalar<long long>(*this, t, prefix, key, fallback, "an integer");
  if (v < lo || v > hi)
    fail(t.get(key), join(prefix, key),
         "must be an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], not " + std::to_string(v));
  return v;
}

bool TomlFile::boolean(const toml::table& t, const std::string& prefix, const std::string& key,
                       std::optional<bool> fallback) const {
  return scalar<bool>(*this, t, prefix, key, fallback, "true or false");
}

std::string TomlFile::string(const toml::table& t, const std::string& prefix,
                             const std::string& key, std::optional<std::string> fallback) const {
  return scalar<std::string>(*this, t, prefix, key, fallback, "a string");
}

std::vector<double> TomlFile::numbers(const toml::table& t, const std::string& prefix,
                                      const std::string& key, size_t min_len,
                                      size_t max_len) const {
  const toml::node* n = t.get(key);
  const std::string k = join(prefix, key);
  if (!n) fail(&t, k, "missing (an array of numbers is required)");
  const toml::array* a = n->as_array();
  if (!a) fail(n, k, "expected an array of numbers");
  if (a->size() < min_len || a->size() > max_len) {
    std::ostringstream os;
    os << "expected " << min_len;
    if (max_len != min_len) os << " to " << max_len;
    os << " numbers, got " << a->size();
    fail(n, k, os.str());
  }
  std::vector<double> out;
  for (size_t i = 0; i < a->size(); ++i) {
    const toml::node& e = *a->get(i);
    if (!e.is_number()) fail(&e, k + "[" + std::to_string(i) + "]", "expected a number");
    const double v = e.value<double>().value();
    if (!std::isfinite(v)) fail(&e, k + "[" + std::to_string(i) + "]", "must be finite");
    out.push_back(v);
  }
  return out;
}

std::vector<std::string> TomlFile::strings(const toml::table& t, const std::string& prefix,
                                           const std::string& key) const {
  const toml::node* n = t.get(key);
  const std::string k = join(prefix, key);
  if (!n) return {};
  const toml::array* a = n->as_array();
  if (!a) fail(n, k, "expected an array of strings");
  std::vector<std::string> out;
  for (size_t i = 0; i < a->size(); ++i) {
    const toml::node& e = *a->get(i);
    if (!e.is_string()) fail(&e, k + "[" + std::to_string(i) + "]", "expected a string");
    out.push_back(e.value<std::string>().value());
  }
  return out;
}

const toml::table* TomlFile::table(const toml::table& t, const std::string& prefix,
                                   const std::string& key, bool required) const {
  const toml::node* n = t.get(key);
  const std::string k = join(prefix, key);
  if (!n) {
    if (required) fail(&t, k, "missing (a table [" + k + "] is required)");
    return nullptr;
  }
  const toml::table* tt = n->as_table();
  if (!tt) fail(n, k, "expected a table");
  return tt;
}

void TomlFile::only_keys(const toml::table& t, const std::string& prefix,
                         const std::vector<std::string>& allowed) const {
  for (const auto& [key, node] : t) {
    const std::string k(key.str());
    if (std::find(allowed.begin(), allowed.end(), k) == allowed.end()) {
      std::string list;
      for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
      fail(&node, join(prefix, k), "unknown key (allowed here: " + list + ")");
    }
  }
}

}  // namespace hapticloth::app
