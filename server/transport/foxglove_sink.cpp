#include "transport/foxglove_sink.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "cloth/cool_warm.hpp"
#include "foxglove_bridge.h"
#include "hapticloth/cloth_state_t.hpp"
#include "hapticloth/cloth_topology_t.hpp"
#include "hapticloth/event_t.hpp"
#include "hapticloth/tactile_state_t.hpp"
#include "hapticloth/haptic_state_t.hpp"
#include "hapticloth/loop_stats_t.hpp"
#include "hapticloth/scene_info_t.hpp"
#include "zenoh_bridge.h"

namespace hapticloth::transport {

namespace {

// The strain at either end of the colour scale: hapticloth-render's default range (1%).
constexpr double kStrainRange = 0.01;
// m of force arrow per N on /fingertips (hapticloth-render's default).
constexpr double kMetresPerNewton = 0.02;

std::string bridge_error() {
  char buf[512];
  hz_last_error(buf, sizeof buf);
  return buf;
}

// JSON schemas (draft 2020-12) of the two JSON channels, so that Foxglove and PlotJuggler see
// the fields' types before the first message.
nlohmann::json object_schema(nlohmann::json properties) {
  return {{"type", "object"}, {"properties", std::move(properties)}};
}

nlohmann::json number_schema(const char* description = nullptr) {
  nlohmann::json j = {{"type", "number"}};
  if (description) j["description"] = description;
  return j;
}

nlohmann::json quantiles_schema() {
  return object_schema({{"p50", number_schema()}, {"p99", number_schema()}, {"p999", number_schema()},
                        {"max", number_schema()}});
}

std::string haptics_schema() {
  const nlohmann::json v = object_schema({{"x", number_schema()}, {"y", number_schema()}, {"z", number_schema()}});
  const nlohmann::json finger = object_schema({{"force", v},
                                               {"force_magnitude", number_schema("N")},
                                               {"position", v},
                                               {"proxy", v},
                                               {"contact", {{"type", "boolean"}}},
                                               {"slipping", {{"type", "boolean"}}}});
  nlohmann::json j = object_schema({{"time", number_schema("s, loop clock")},
                                    {"tick", {{"type", "integer"}}},
                                    {"fingers", {{"type", "array"}, {"items", finger}}}});
  j["$schema"] = "https://json-schema.org/draft/2020-12/schema";
  j["title"] = "hapticloth.Haptics";
  j["description"] = "The last haptic tick of a haptic_state_t batch (scene frame; m, N)";
  return j.dump();
}

std::string tactile_schema() {
  const nlohmann::json finger = object_schema({{"vibration_rms", number_schema("m, over the message's ticks")},
                                               {"vibration", {{"type", "array"}, {"items", number_schema("m")}}},
                                               {"u", number_schema("m, along the weft")},
                                               {"v", number_schema("m, along the warp")},
                                               {"normal_force", number_schema("N")},
                                               {"touching", {{"type", "boolean"}}}});
  nlohmann::json j = object_schema({{"time", number_schema("s, loop clock")},
                                    {"tick", {{"type", "integer"}}},
                                    {"fingers", {{"type", "array"}, {"items", finger}}}});
  j["$schema"] = "https://json-schema.org/draft/2020-12/schema";
  return j.dump();
}

std::string loop_schema() {
  nlohmann::json j = object_schema({{"ticks", {{"type", "integer"}}},
                                    {"missed_deadlines", {{"type", "integer"}}},
                                    {"period_error_us", quantiles_schema()},
                                    {"compute_us", quantiles_schema()}});
  j["$schema"] = "https://json-schema.org/draft/2020-12/schema";
  j["title"] = "hapticloth.LoopStats";
  j["description"] = "Haptic loop timing since the session started (loop_stats_t)";
  return j.dump();
}

nlohmann::json vec3(const float v[3]) { return {{"x", v[0]}, {"y", v[1]}, {"z", v[2]}}; }

// foxglove.Log levels: 2 info, 3 warning.
int level_of(const std::string& kind) {
  static const char* const kWarnings[] = {"watchdog", "nan", "dropped_packets", "command_rejected",
                                          "device_failed", "stopping"};
  for (const char* w : kWarnings)
    if (kind == w) return 3;
  return 2;
}

// The big-endian int32 at `at`, or -1 past the end.
std::int64_t be32(const std::uint8_t* b, std::size_t len, std::size_t at) {
  if (at + 4 > len) return -1;
  return static_cast<std::int32_t>((std::uint32_t(b[at]) << 24) | (std::uint32_t(b[at + 1]) << 16) |
                                   (std::uint32_t(b[at + 2]) << 8) | std::uint32_t(b[at + 3]));
}

// LCM's generated decode sizes every array from its count before it reads the elements, so a
// message whose counts are corrupt would make it allocate gigabytes. The counts that lead a
// message (after the 8-byte fingerprint and its fixed fields) must fit in its bytes: each
// element takes at least its size on the wire.
bool counts_fit(Topic t, const std::uint8_t* b, std::size_t len) {
  const auto fits = [&](std::int64_t count, std::int64_t bytes_each) {
    return count >= 0 && count * bytes_each <= static_cast<std::int64_t>(len);
  };
  switch (t) {
    case Topic::Cloth: return fits(be32(b, len, 32), 12);  // utime, time, step; float[n][3]
    case Topic::Topology: return fits(be32(b, len, 16), 12) && fits(be32(b, len, 20), 12);
    case Topic::Haptics: {  // utime; num_samples, num_fingers; double time[n], float[n][f][3] x5
      const std::int64_t n = be32(b, len, 16), f = be32(b, len, 20);
      return fits(n, 16) && fits(f, 1) && fits(n * f, 60);
    }
    case Topic::Tactile: {  // utime; ticks, fingers, samples, rows, cols, pins; double time[n], ...
      const std::int64_t n = be32(b, len, 16), f = be32(b, len, 20), sm = be32(b, len, 24), p = be32(b, len, 36);
      return fits(n, 16) && fits(f, 1) && fits(n * f, 13) && fits(n * f * sm, 4) && fits(n * f * p, 4);
    }
    default: return true;  // strings first: LCM checks each string's length against the bytes
  }
}

}  // namespace

void parse_host_port(const std::string& s, const std::string& what, std::string& host, std::uint16_t& port) {
  const auto colon = s.rfind(':');
  const auto bad = [&](const std::string& why) {
    throw std::invalid_argument(what + " " + s + ": " + why + " (HOST:PORT, e.g. 127.0.0.1:8765)");
  };
  if (colon == std::string::npos || colon == 0) bad("no host");
  host = s.substr(0, colon);
  const std::string p = s.substr(colon + 1);
  if (p.empty() || p.size() > 5 || p.find_first_not_of("0123456789") != std::string::npos) bad("no port");
  const long v = std::stol(p);
  if (v > 65535) bad("port above 65535");
  port = static_cast<std::uint16_t>(v);
}

const char* FoxgloveSink::channel_name(Channel c) {
  static const char* const kNames[kChannels] = {"/cloth", "/fingertips", "/haptics", "/loop", "/events",
                                                "/tactile", "/tactile/pins"};
  return kNames[c];
}

FoxgloveSink::FoxgloveSink(const FoxgloveOptions& opt) : opt_(opt) {
  std::string host;
  std::uint16_t port = 0;
  if (!opt.live.empty()) parse_host_port(opt.live, "--foxglove", host, port);
  sink_ = hf_open(opt.live.empty() ? nullptr : host.c_str(), port, opt.mcap.empty() ? nullptr : opt.mcap.c_str(),
                  opt.server_name.c_str(), "scene");
  if (!sink_)
    throw FoxgloveOpenError("foxglove: cannot open " +
                             std::string(opt.live.empty() ? "--mcap " + opt.mcap : "--foxglove " + opt.live) +
                             ": " + bridge_error());
  const std::string hs = haptics_schema(), ls = loop_schema(), ts = tactile_schema();
  if (hf_declare_json(sink_, HF_JSON_HAPTICS, "hapticloth.Haptics", hs.c_str()) != 0 ||
      hf_declare_json(sink_, HF_JSON_LOOP, "hapticloth.LoopStats", ls.c_str()) != 0 ||
      hf_declare_json(sink_, HF_JSON_TACTILE, "hapticloth.Tactile", ts.c_str()) != 0) {
    const std::string e = bridge_error();
    hf_close(sink_);
    sink_ = nullptr;
    throw FoxgloveOpenError("foxglove: " + e);
  }
  port_ = hf_port(sink_);
}

FoxgloveSink::~FoxgloveSink() {
  try {
    close();
  } catch (const std::exception&) {  // said by close() when called explicitly
  }
}

void FoxgloveSink::close() {
  if (!sink_) return;
  const int rc = hf_close(sink_);
  sink_ = nullptr;
  if (rc != 0) throw std::runtime_error("foxglove: --mcap " + opt_.mcap + ": " + bridge_error());
}

bool FoxgloveSink::wants(Topic t) const {
  if (!sink_) return false;
  switch (t) {
    case Topic::Topology:
    case Topic::Scene: return true;
    case Topic::Cloth: return hf_wants(sink_, HF_CLOTH);
    case Topic::Haptics: return hf_wants(sink_, HF_HAPTICS) || hf_wants(sink_, HF_FINGERTIPS);
    case Topic::Stats: return hf_wants(sink_, HF_LOOP);
    case Topic::Events: return hf_wants(sink_, HF_EVENTS);
    case Topic::Tactile: return hf_wants(sink_, HF_TACTILE) || hf_wants(sink_, HF_TACTILE_PINS);
  }
  return false;
}

template <class M>
bool FoxgloveSink::decode(const std::uint8_t* bytes, std::size_t len, M& m) {
  try {
    if (len <= static_cast<std::size_t>(INT32_MAX) && m.decode(bytes, 0, static_cast<int>(len)) >= 0) return true;
  } catch (const std::exception&) {  // std::bad_alloc, std::length_error from a corrupt count
  }
  ++undecodable_;
  return false;
}

void FoxgloveSink::send(Topic t, const std::uint8_t* bytes, std::size_t len, std::int64_t utime) {
  if (!sink_) return;
  const std::uint64_t ns = static_cast<std::uint64_t>(std::max<std::int64_t>(utime, 0)) * 1000u;
  if (!counts_fit(t, bytes, len)) {
    ++undecodable_;
    return;
  }
  switch (t) {
    case Topic::Topology: {
      hapticloth::cloth_topology_t m{};
      if (decode(bytes, len, m)) take_topology(m);
      break;
    }
    case Topic::Scene: {
      hapticloth::scene_info_t m{};
      if (decode(bytes, len, m)) take_topology(m.topology);
      break;
    }
    case Topic::Cloth: cloth(bytes, len, ns); break;
    case Topic::Haptics: haptics(bytes, len, ns); break;
    case Topic::Stats: loop(bytes, len, ns); break;
    case Topic::Events: event(bytes, len, ns); break;
    case Topic::Tactile: tactile(bytes, len, ns); break;
  }
}

// The mesh, once (it is fixed for a run): triangles and each triangle's eq. 2 rest element
// for the strains. A triangle degenerate in weave space gets no strain (grey).
void FoxgloveSink::take_topology(const hapticloth::cloth_topology_t& t) {
  if (vertices_ > 0) return;
  const int nt = t.num_triangles;
  triangles_.resize(3 * static_cast<std::size_t>(nt));
  rest_.resize(nt);
  degenerate_.assign(nt, false);
  for (int i = 0; i < nt; ++i) {
    double uv[3][2];
    for (int k = 0; k < 3; ++k) {
      const int v = t.triangles[i][k];
      if (v < 0 || v >= t.num_vertices) {  // not a mesh: keep waiting for a good one
        ++undecodable_;
        triangles_.clear();
        return;
      }
      triangles_[3 * i + k] = static_cast<std::uint32_t>(v);
      for (int j = 0; j < 2; ++j) uv[k][j] = t.weave_uv[i][k][j];
    }
    try {
      rest_[i] = cloth::make_element(t.triangles[i][0], t.triangles[i][1], t.triangles[i][2], uv);
    } catch (const std::invalid_argument&) {
      degenerate_[i] = true;
    }
  }
  vertices_ = static_cast<std::size_t>(t.num_vertices);
}

// Per vertex of x from `first` on: the eq. 4 strain of largest magnitude of each of its
// triangles (rest[i], skipped where degenerate[i]), averaged, on the fixed scale, into rgba.
void FoxgloveSink::strain_colours(const std::vector<std::vector<float>>& x, std::size_t first,
                                  const std::vector<cloth::ElementRest>& rest, const std::vector<bool>& degenerate) {
  const std::size_t nv = x.size();
  sum_.assign(nv, 0.0);
  weight_.assign(nv, 0.0f);
  const auto at = [&](int v) { return cloth::Vec3(x[v][0], x[v][1], x[v][2]); };
  for (std::size_t i = 0; i < rest.size(); ++i) {
    if (degenerate[i]) continue;
    const cloth::ElementRest& e = rest[i];
    const cloth::Strains s = cloth::element_strains(e, at(e.v[0]), at(e.v[1]), at(e.v[2]));
    double m = s.uu;
    if (std::abs(s.vv) > std::abs(m)) m = s.vv;
    if (std::abs(s.uv) > std::abs(m)) m = s.uv;
    for (int k = 0; k < 3; ++k) {
      sum_[e.v[k]] += m;
      weight_[e.v[k]] += 1.0f;
    }
  }
  rgba_.resize(4 * (first + nv));
  for (std::size_t v = 0; v < nv; ++v) {
    const double strain = weight_[v] > 0 ? sum_[v] / weight_[v] : std::nan("");
    const std::array<double, 3> c = cloth::cool_warm(strain / kStrainRange);
    for (int k = 0; k < 3; ++k) rgba_[4 * (first + v) + k] = static_cast<float>(c[k] / 255.0);
    rgba_[4 * (first + v) + 3] = 1.0f;
  }
}

// The refined children (paper 4.2.2) in place of the global triangles they stand in for: their
// vertices after the global ones, their triangles instead of the region's, coloured by their
// own strains. False (and nothing added) if the fields do not make a mesh.
bool FoxgloveSink::add_refined(const hapticloth::cloth_state_t& m) {
  const std::size_t nv = m.refined_positions.size(), nt = m.refined_triangles.size();
  if (nt == 0) return true;
  child_rest_.resize(nt);
  child_degenerate_.assign(nt, false);
  for (std::size_t i = 0; i < nt; ++i) {
    double uv[3][2];
    for (int k = 0; k < 3; ++k) {
      const int v = m.refined_triangles[i][k];
      if (v < 0 || static_cast<std::size_t>(v) >= nv) return false;
      for (int j = 0; j < 2; ++j) uv[k][j] = m.refined_weave_uv[i][k][j];
    }
    try {
      child_rest_[i] = cloth::make_element(m.refined_triangles[i][0], m.refined_triangles[i][1],
                                           m.refined_triangles[i][2], uv);
    } catch (const std::invalid_argument&) {
      child_degenerate_[i] = true;
    }
  }
  for (const int t : m.refined_region)
    if (t < 0 || static_cast<std::size_t>(t) >= hidden_.size()) return false;
  for (const int t : m.refined_region) hidden_[t] = true;
  std::size_t kept = 0;  // the global triangles left, then the children's
  for (std::size_t t = 0; t < hidden_.size(); ++t) {
    if (hidden_[t]) continue;
    for (int k = 0; k < 3; ++k) tris_[3 * kept + k] = triangles_[3 * t + k];
    ++kept;
  }
  tris_.resize(3 * kept);
  for (std::size_t i = 0; i < nt; ++i)
    for (int k = 0; k < 3; ++k) tris_.push_back(static_cast<std::uint32_t>(vertices_ + m.refined_triangles[i][k]));
  for (std::size_t v = 0; v < nv; ++v)
    for (int k = 0; k < 3; ++k) xyz_.push_back(m.refined_positions[v][k]);
  strain_colours(m.refined_positions, vertices_, child_rest_, child_degenerate_);
  return true;
}

void FoxgloveSink::cloth(const std::uint8_t* bytes, std::size_t len, std::uint64_t ns) {
  hapticloth::cloth_state_t m{};
  if (!decode(bytes, len, m)) return;
  if (vertices_ == 0 || m.positions.size() != vertices_) {
    ++before_topology_;
    return;
  }
  xyz_.resize(3 * vertices_);
  for (std::size_t v = 0; v < vertices_; ++v)
    for (int k = 0; k < 3; ++k) xyz_[3 * v + k] = m.positions[v][k];
  strain_colours(m.positions, 0, rest_, degenerate_);
  tris_ = triangles_;
  hidden_.assign(triangles_.size() / 3, false);
  if (!add_refined(m)) {  // the global cloth alone
    ++undecodable_;
    tris_ = triangles_;
    xyz_.resize(3 * vertices_);
    rgba_.resize(4 * vertices_);
  }
  hf_cloth(sink_, ns, xyz_.data(), rgba_.data(), static_cast<std::uint32_t>(xyz_.size() / 3), tris_.data(),
           static_cast<std::uint32_t>(tris_.size() / 3));
  ++written_[Cloth];
}

// The batch's last sample: /fingertips (proxy spheres, force arrows) and /haptics.
void FoxgloveSink::haptics(const std::uint8_t* bytes, std::size_t len, std::uint64_t ns) {
  hapticloth::haptic_state_t m{};
  if (!decode(bytes, len, m) || m.num_samples < 1 || m.num_fingers < 1) return;
  const int k = m.num_samples - 1, nf = m.num_fingers;
  std::vector<float> centres(3 * nf), forces(3 * nf);
  std::vector<std::uint8_t> contact(nf);
  nlohmann::json fingers = nlohmann::json::array();
  for (int f = 0; f < nf; ++f) {
    const float* force = m.force[k][f].data();
    for (int c = 0; c < 3; ++c) {
      centres[3 * f + c] = m.proxy[k][f][c];
      forces[3 * f + c] = force[c];
    }
    contact[f] = m.in_contact[k][f] ? 1 : 0;
    fingers.push_back({{"force", vec3(force)},
                       {"force_magnitude", std::sqrt(force[0] * force[0] + force[1] * force[1] + force[2] * force[2])},
                       {"position", vec3(m.position[k][f].data())},
                       {"proxy", vec3(m.proxy[k][f].data())},
                       {"contact", static_cast<bool>(m.in_contact[k][f])},
                       {"slipping", static_cast<bool>(m.slipping[k][f])}});
  }
  hf_fingertips(sink_, ns, static_cast<std::uint32_t>(nf), centres.data(), forces.data(), contact.data(),
                opt_.finger_radius, kMetresPerNewton);
  ++written_[Fingertips];
  const std::string j = nlohmann::json{{"time", m.time[k]}, {"tick", m.tick[k]}, {"fingers", fingers}}.dump();
  hf_json(sink_, HF_JSON_HAPTICS, ns, reinterpret_cast<const std::uint8_t*>(j.data()), j.size());
  ++written_[Haptics];
}

// /tactile: per finger the vibration's RMS over the message's ticks (about 100 Hz: a plot of
// the texture's strength), its last block, and where on the fabric the finger is; /tactile/pins:
// the last tick's pin frames side by side, kPinPixels pixels a pin, mid-grey level, +-kPinScale
// m to white and black.
void FoxgloveSink::tactile(const std::uint8_t* bytes, std::size_t len, std::uint64_t ns) {
  hapticloth::tactile_state_t m{};
  if (!decode(bytes, len, m) || m.num_ticks < 1 || m.num_fingers < 1) return;
  const int k = m.num_ticks - 1, nf = m.num_fingers;
  nlohmann::json fingers = nlohmann::json::array();
  for (int f = 0; f < nf; ++f) {
    double ss = 0.0;
    for (int t = 0; t < m.num_ticks; ++t)
      for (float x : m.vibration[t][f]) ss += static_cast<double>(x) * x;
    const double n = static_cast<double>(m.num_ticks) * std::max(1, m.samples_per_tick);
    fingers.push_back({{"vibration_rms", std::sqrt(ss / n)},
                       {"vibration", m.vibration[k][f]},
                       {"u", m.u[k][f]},
                       {"v", m.v[k][f]},
                       {"normal_force", m.normal_force[k][f]},
                       {"touching", static_cast<bool>(m.touching[k][f])}});
  }
  const std::string j = nlohmann::json{{"time", m.time[k]}, {"tick", m.tick[k]}, {"fingers", fingers}}.dump();
  hf_json(sink_, HF_JSON_TACTILE, ns, reinterpret_cast<const std::uint8_t*>(j.data()), j.size());
  ++written_[Tactile];
  if (m.num_pins < 1 || m.rows < 1 || m.cols < 1 || m.rows * m.cols != m.num_pins) return;
  constexpr int kPinPixels = 8;
  constexpr double kPinScale = 50e-6;
  const int w = nf * m.cols * kPinPixels + (nf - 1) * kPinPixels, h = m.rows * kPinPixels;
  std::vector<std::uint8_t> grey(static_cast<std::size_t>(w) * h, 0);
  for (int f = 0; f < nf; ++f)
    for (int i = 0; i < m.rows; ++i)
      for (int jc = 0; jc < m.cols; ++jc) {
        const double z = std::clamp(m.pins[k][f][i * m.cols + jc] / kPinScale, -1.0, 1.0);
        const auto level = static_cast<std::uint8_t>(std::lround(127.5 + 127.5 * z));
        const int x0 = (f * (m.cols + 1) + jc) * kPinPixels, y0 = i * kPinPixels;
        for (int y = 0; y < kPinPixels; ++y)
          std::fill_n(grey.begin() + static_cast<long>((y0 + y) * w + x0), kPinPixels, level);
      }
  hf_pins(sink_, ns, static_cast<std::uint32_t>(w), static_cast<std::uint32_t>(h), grey.data());
  ++written_[TactilePins];
}

void FoxgloveSink::loop(const std::uint8_t* bytes, std::size_t len, std::uint64_t ns) {
  hapticloth::loop_stats_t m{};
  if (!decode(bytes, len, m)) return;
  const nlohmann::json j = {
      {"ticks", m.ticks},
      {"missed_deadlines", m.missed_deadlines},
      {"period_error_us", {{"p50", m.period_error_p50_us}, {"p99", m.period_error_p99_us},
                           {"p999", m.period_error_p999_us}, {"max", m.period_error_max_us}}},
      {"compute_us", {{"p50", m.compute_p50_us}, {"p99", m.compute_p99_us},
                      {"p999", m.compute_p999_us}, {"max", m.compute_max_us}}}};
  const std::string s = j.dump();
  hf_json(sink_, HF_JSON_LOOP, ns, reinterpret_cast<const std::uint8_t*>(s.data()), s.size());
  ++written_[Loop];
}

void FoxgloveSink::event(const std::uint8_t* bytes, std::size_t len, std::uint64_t ns) {
  hapticloth::event_t m{};
  if (!decode(bytes, len, m)) return;
  if (hf_event(sink_, ns, level_of(m.kind), m.kind.c_str(), m.text.c_str()) != 0) {
    ++undecodable_;  // a kind or text that is not UTF-8
    return;
  }
  ++written_[Events];
}

}  // namespace hapticloth::transport
