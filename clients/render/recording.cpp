#include "render/recording.hpp"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>

#include <lcm/eventlog.h>

#include "hapticloth/cloth_state_t.hpp"
#include "hapticloth/cloth_topology_t.hpp"
#include "hapticloth/haptic_state_t.hpp"
#include "hapticloth/scene_info_t.hpp"

namespace hapticloth::render {

namespace {

// The first 8 bytes of an LCM message are its type fingerprint, big-endian.
std::int64_t fingerprint(const std::uint8_t* data, std::size_t len) {
  if (len < 8) return 0;
  std::uint64_t h = 0;
  for (int i = 0; i < 8; ++i) h = (h << 8) | data[i];
  return static_cast<std::int64_t>(h);
}

template <class M>
bool decode(const std::uint8_t* data, std::size_t len, M& m) {
  return m.decode(data, 0, static_cast<int>(len)) >= 0;
}

Vec3f vec(const float p[3]) { return Vec3f(p[0], p[1], p[2]); }

void set_topology(Recording& rec, const hapticloth::cloth_topology_t& t) {
  Scene& s = rec.scene;
  s.triangles.resize(t.num_triangles);
  s.weave_uv.resize(t.num_triangles);
  for (int i = 0; i < t.num_triangles; ++i)
    for (int k = 0; k < 3; ++k) {
      s.triangles[i][k] = t.triangles[i][k];
      s.weave_uv[i][k] = {t.weave_uv[i][k][0], t.weave_uv[i][k][1]};
    }
  s.rest_positions.resize(t.num_vertices);
  for (int i = 0; i < t.num_vertices; ++i) s.rest_positions[i] = vec(t.rest_positions[i].data());
  rec.has_topology = true;
}

// The refined children of a cloth state; false if their triangles index vertices they lack.
bool set_refined(RefinedFrame& r, const hapticloth::cloth_state_t& m) {
  r.positions.resize(m.num_refined_vertices);
  for (int i = 0; i < m.num_refined_vertices; ++i) r.positions[i] = vec(m.refined_positions[i].data());
  r.mesh.triangles.resize(m.num_refined_triangles);
  r.mesh.weave_uv.resize(m.num_refined_triangles);
  for (int i = 0; i < m.num_refined_triangles; ++i)
    for (int k = 0; k < 3; ++k) {
      const int v = m.refined_triangles[i][k];
      if (v < 0 || v >= m.num_refined_vertices) return false;
      r.mesh.triangles[i][k] = v;
      r.mesh.weave_uv[i][k] = {m.refined_weave_uv[i][k][0], m.refined_weave_uv[i][k][1]};
    }
  r.region.assign(m.refined_region.begin(), m.refined_region.end());
  return true;
}

// A topology whose indices are out of range cannot be drawn: treat it like a corrupt message.
bool valid(const hapticloth::cloth_topology_t& t) {
  for (const auto& tri : t.triangles)
    for (int v : tri)
      if (v < 0 || v >= t.num_vertices) return false;
  return true;
}

}  // namespace

bool add_message(Recording& rec, const std::uint8_t* data, std::size_t len) {
  const std::int64_t h = fingerprint(data, len);
  if (h == hapticloth::cloth_state_t::getHash()) {
    hapticloth::cloth_state_t m;
    if (!decode(data, len, m)) return false;
    ClothFrame f;
    f.time = m.time;
    f.step = m.step;
    f.positions.resize(m.num_vertices);
    for (int i = 0; i < m.num_vertices; ++i) f.positions[i] = vec(m.positions[i].data());
    if (!set_refined(f.refined, m)) return false;
    rec.frames.push_back(std::move(f));
    return true;
  }
  if (h == hapticloth::haptic_state_t::getHash()) {
    hapticloth::haptic_state_t m;
    if (!decode(data, len, m)) return false;
    for (int k = 0; k < m.num_samples; ++k) {
      HapticTick t;
      t.time = m.time[k];
      t.tick = m.tick[k];
      t.fingers.resize(m.num_fingers);
      for (int f = 0; f < m.num_fingers; ++f) {
        FingerSample& s = t.fingers[f];
        s.position = vec(m.position[k][f].data());
        s.proxy = vec(m.proxy[k][f].data());
        s.force = vec(m.force[k][f].data());
        s.contact = m.in_contact[k][f];
      }
      rec.haptics.push_back(std::move(t));
    }
    return true;
  }
  if (h == hapticloth::cloth_topology_t::getHash()) {
    hapticloth::cloth_topology_t m;
    if (!decode(data, len, m) || !valid(m)) return false;
    set_topology(rec, m);
    return true;
  }
  if (h == hapticloth::scene_info_t::getHash()) {
    hapticloth::scene_info_t m;
    if (!decode(data, len, m)) return false;
    rec.scene.name = m.scene_name;
    rec.scene.haptic_rate = m.haptic_rate;
    if (!rec.has_topology && m.topology.num_vertices > 0 && valid(m.topology))
      set_topology(rec, m.topology);
    return true;
  }
  return false;
}

void finish(Recording& rec) {
  const std::size_t n = rec.scene.rest_positions.size();
  const int nt = static_cast<int>(rec.scene.triangles.size());
  const auto wrong = [n, nt](const ClothFrame& f) {
    return f.positions.size() != n ||
           std::any_of(f.refined.region.begin(), f.refined.region.end(), [nt](int t) { return t < 0 || t >= nt; });
  };
  const auto before = rec.frames.size();
  rec.frames.erase(std::remove_if(rec.frames.begin(), rec.frames.end(), wrong), rec.frames.end());
  rec.dropped += before - rec.frames.size();
  std::stable_sort(rec.frames.begin(), rec.frames.end(),
                   [](const ClothFrame& a, const ClothFrame& b) { return a.time < b.time; });
  std::stable_sort(rec.haptics.begin(), rec.haptics.end(),
                   [](const HapticTick& a, const HapticTick& b) { return a.time < b.time; });
}

std::size_t Recording::frame_near(double time) const {
  const auto it = std::lower_bound(frames.begin(), frames.end(), time,
                                   [](const ClothFrame& f, double t) { return f.time < t; });
  if (it == frames.end()) return frames.size() - 1;
  const std::size_t i = static_cast<std::size_t>(it - frames.begin());
  if (i > 0 && time - frames[i - 1].time <= it->time - time) return i - 1;
  return i;
}

const HapticTick* Recording::haptics_at(double time) const {
  if (haptics.empty()) return nullptr;
  const auto it = std::upper_bound(haptics.begin(), haptics.end(), time,
                                   [](double t, const HapticTick& h) { return t < h.time; });
  return it == haptics.begin() ? &haptics.front() : &*(it - 1);
}

Recording read_lcm_log(const std::string& path) {
  std::error_code ec;
  const auto st = std::filesystem::status(path, ec);
  if (!std::filesystem::exists(st))
    throw InputError(path + ": cannot open as an LCM log (no such file)");
  if (!std::filesystem::is_regular_file(st))  // /dev/zero would be read for ever
    throw InputError(path + ": not a regular file (a device, FIFO or socket is not read as input)");
  std::unique_ptr<lcm_eventlog_t, void (*)(lcm_eventlog_t*)> log(
      lcm_eventlog_create(path.c_str(), "r"), lcm_eventlog_destroy);
  if (!log) throw InputError(path + ": cannot open as an LCM log (not readable)");
  Recording rec;
  while (lcm_eventlog_event_t* ev = lcm_eventlog_read_next_event(log.get())) {
    add_message(rec, static_cast<const std::uint8_t*>(ev->data), ev->datalen);
    lcm_eventlog_free_event(ev);
  }
  if (!rec.has_topology)
    throw InputError(path +
                     ": no cloth_topology_t message (was the log written by hapticloth-server?)");
  finish(rec);
  return rec;
}

}  // namespace hapticloth::render
