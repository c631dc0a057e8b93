// Reading TOML configuration with errors that name the file, the line and the key.
#pragma once

#include <array>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <toml++/toml.h>

namespace hapticloth::app {

/// Bad user input in a file: the message reads "FILE:LINE: key 'a.b': what is wrong".
class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A parsed TOML file and typed accessors. Every accessor takes the table, its dotted prefix
/// (for messages) and the key; missing required keys, wrong types, non-finite numbers and
/// unknown keys are ConfigErrors.
class TomlFile {
 public:
  /// Throws ConfigError if the file cannot be read or is not valid TOML.
  static TomlFile load(const std::string& path);
  static TomlFile parse(const std::string& text, const std::string& name);

  const std::string& path() const { return path_; }
  const toml::table& root() const { return root_; }

  [[noreturn]] void fail(const toml::node* at, const std::string& key,
                         const std::string& what) const;

  const toml::node* find(const toml::table& t, const std::string& key) const;
  double number(const toml::table& t, const std::string& prefix, const std::string& key,
                std::optional<double> fallback = std::nullopt) const;
  /// A number in [lo, hi] (> lo with `open_lo`); outside, the key is named with the range in
  /// `unit` ("m", "Hz").
  double number_in(const toml::table& t, const std::string& prefix, const std::string& key,
                   std::optional<double> fallback, double lo, double hi, const std::string& unit,
                   bool open_lo = false) const;
  /// An integer in [lo, hi]; anything outside (also past 2^31 or 2^63) names the key and range.
  long long integer(const toml::table& t, const std::string& prefix, const std::string& key,
                    std::optional<long long> fallback, long long lo, long long hi) const;
  bool boolean(const toml::table& t, const std::string& prefix, const std::string& key,
               std::optional<bool> fallback = std::nullopt) const;
  std::string string(const toml::table& t, const std::string& prefix, const std::string& key,
                     std::optional<std::string> fallback = std::nullopt) const;
  /// Array of numbers with a length in [min_len, max_len].
  std::vector<double> numbers(const toml::table& t, const std::string& prefix,
                              const std::string& key, size_t min_len, size_t max_len) const;
  std::vector<std::string> strings(const toml::table& t, const std::string& prefix,
                                   const std::string& key) const;
  /// Sub-table; null if absent and not required.
  const toml::table* table(const toml::table& t, const std::string& prefix, const std::string& key,
                           bool required) const;
  /// Rejects keys outside `allowed` (catches typos that would otherwise be ignored).
  void only_keys(const toml::table& t, const std::string& prefix,
                 const std::vector<std::string>& allowed) const;

  static std::string join(const std::string& prefix, const std::string& key) {
    return prefix.empty() ? key : prefix + "." + key;
  }

 private:
  std::string path_;
  toml::table root_;
};

}  // namespace hapticloth::app
