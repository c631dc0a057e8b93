#include "transport/codec.hpp"

#include <chrono>

#include "cloth/material.hpp"
#include "cloth/mesh.hpp"

namespace hapticloth::transport {

std::int64_t wall_utime() {
  using namespace std::chrono;
  return duration_cast<microseconds>(system_clock::now().time_since_epoch()).count();
}

void set_cloth(SceneInfo& info, const cloth::Mesh& mesh, const cloth::Material& material) {
  info.triangles = mesh.triangles;
  info.rest_positions = mesh.positions;
  info.weave_uv = mesh.weave_uv;
  info.material_name = material.name;
  info.areal_density = material.areal_density;
  info.weft_period = material.surface.weft.empty() ? 0.0 : material.surface.weft.period();
  info.warp_period = material.surface.warp.empty() ? 0.0 : material.surface.warp.period();
}

LoopSummary summarize(const haptics::LoopStats& s) noexcept {
  LoopSummary r;
  r.ticks = s.ticks;
  r.missed = s.missed_deadlines;
  r.period_p50 = static_cast<float>(s.period_error_us.quantile(0.5));
  r.period_p99 = static_cast<float>(s.period_error_us.quantile(0.99));
  r.period_p999 = static_cast<float>(s.period_error_us.quantile(0.999));
  r.period_max = static_cast<float>(s.period_error_us.max());
  r.compute_p50 = static_cast<float>(s.compute_us.quantile(0.5));
  r.compute_p99 = static_cast<float>(s.compute_us.quantile(0.99));
  r.compute_p999 = static_cast<float>(s.compute_us.quantile(0.999));
  r.compute_max = static_cast<float>(s.compute_us.max());
  return r;
}

void fill(const SceneInfo& info, hapticloth::cloth_topology_t& m) {
  m.utime = wall_utime();
  m.num_vertices = static_cast<int32_t>(info.rest_positions.size());
  m.num_triangles = static_cast<int32_t>(info.triangles.size());
  m.triangles.assign(m.num_triangles, std::vector<int32_t>(3));
  m.weave_uv.assign(m.num_triangles, std::vector<std::vector<float>>(3, std::vector<float>(2)));
  for (int t = 0; t < m.num_triangles; ++t)
    for (int c = 0; c < 3; ++c) {
      m.triangles[t][c] = info.triangles[t][c];
      if (t < static_cast<int>(info.weave_uv.size()))
        for (int k = 0; k < 2; ++k) m.weave_uv[t][c][k] = static_cast<float>(info.weave_uv[t][c][k]);
    }
  m.rest_positions.assign(m.num_vertices, std::vector<float>(3));
  for (int i = 0; i < m.num_vertices; ++i)
    for (int k = 0; k < 3; ++k) m.rest_positions[i][k] = static_cast<float>(info.rest_positions[i][k]);
}

void fill(const LoopSummary& s, hapticloth::loop_stats_t& m) {
  m.utime = wall_utime();
  m.ticks = static_cast<int64_t>(s.ticks);
  m.missed_deadlines = static_cast<int64_t>(s.missed);
  m.period_error_p50_us = s.period_p50;
  m.period_error_p99_us = s.period_p99;
  m.period_error_p999_us = s.period_p999;
  m.period_error_max_us = s.period_max;
  m.compute_p50_us = s.compute_p50;
  m.compute_p99_us = s.compute_p99;
  m.compute_p999_us = s.compute_p999;
  m.compute_max_us = s.compute_max;
}

namespace {
void put3(std::vector<std::vector<std::vector<float>>>& dst, int n, int fingers) {
  dst.resize(n);
  for (auto& s : dst) {
    s.resize(fingers);
    for (auto& f : s) f.resize(3);
  }
}
}  // namespace

void fill(const HapticSample* samples, int n, int fingers, hapticloth::haptic_state_t& m) {
  m.utime = wall_utime();
  m.num_samples = n;
  m.num_fingers = fingers;
  m.time.resize(n);
  m.tick.resize(n);
  m.command_flags.resize(n);
  put3(m.device_position, n, fingers);
  put3(m.position, n, fingers);
  put3(m.proxy, n, fingers);
  put3(m.force, n, fingers);
  put3(m.command, n, fingers);
  m.in_contact.resize(n);
  m.slipping.resize(n);
  for (int k = 0; k < n; ++k) {
    const HapticSample& s = samples[k];
    m.time[k] = s.time;
    m.tick[k] = static_cast<int64_t>(s.tick);
    m.command_flags[k] = s.flags;
    m.in_contact[k].resize(fingers);
    m.slipping[k].resize(fingers);
    for (int f = 0; f < fingers; ++f) {
      for (int c = 0; c < 3; ++c) {
        m.device_position[k][f][c] = s.device[f][c];
        m.position[k][f][c] = s.position[f][c];
        m.proxy[k][f][c] = s.proxy[f][c];
        m.force[k][f][c] = s.force[f][c];
        m.command[k][f][c] = s.command[f][c];
      }
      m.in_contact[k][f] = s.contact[f];
      m.slipping[k][f] = s.slipping[f];
    }
  }
}

void fill(const TactileSample* samples, int n, int fingers, const TactileLayout& layout,
          hapticloth::tactile_state_t& m) {
  m.utime = wall_utime();
  m.num_ticks = n;
  m.num_fingers = fingers;
  m.samples_per_tick = layout.samples;
  m.rows = layout.rows;
  m.cols = layout.cols;
  m.num_pins = layout.rows * layout.cols;
  m.sample_rate = layout.sample_rate;
  m.pin_pitch = layout.pin_pitch;
  m.weft_period = layout.weft_period;
  m.warp_period = layout.warp_period;
  m.time.resize(n);
  m.tick.resize(n);
  m.flags.resize(n);
  auto per_finger = [&](auto& field, int inner) {
    field.resize(n);
    for (auto& a : field) {
      a.resize(fingers);
      if constexpr (requires { a[0].resize(0); })
        for (auto& b : a) b.resize(inner);
    }
  };
  per_finger(m.vibration, layout.samples);
  per_finger(m.pins, m.num_pins);
  per_finger(m.u, 0);
  per_finger(m.v, 0);
  per_finger(m.normal_force, 0);
  per_finger(m.touching, 0);
  for (int k = 0; k < n; ++k) {
    const TactileSample& s = samples[k];
    m.time[k] = s.time;
    m.tick[k] = static_cast<int64_t>(s.tick);
    m.flags[k] = static_cast<std::int32_t>(s.out.flags);
    for (int f = 0; f < fingers; ++f) {
      const devices::TactileFrame& fr = s.out.finger[f];
      for (int i = 0; i < layout.samples; ++i) m.vibration[k][f][i] = i < fr.samples ? fr.vibration[i] : 0.0f;
      const bool pins = fr.rows == layout.rows && fr.cols == layout.cols;
      for (int i = 0; i < m.num_pins; ++i) m.pins[k][f][i] = pins ? fr.pins[i] : 0.0f;
      m.u[k][f] = s.u[f];
      m.v[k][f] = s.v[f];
      m.normal_force[k][f] = s.normal_force[f];
      m.touching[k][f] = s.touching[f];
    }
  }
}

std::string to_device_command(const hapticloth::trajectory_cmd_t& m, const SceneInfo& info,
                              devices::TrajectoryCommand& out) {
  if (m.frame != hapticloth::trajectory_cmd_t::FRAME_DEVICE &&
      m.frame != hapticloth::trajectory_cmd_t::FRAME_SCENE)
    return "unknown frame " + std::to_string(m.frame);
  if (m.num_points < 0 || static_cast<int>(m.times.size()) != m.num_points ||
      static_cast<int>(m.positions.size()) != m.num_points)
    return "malformed point arrays";
  out.finger = m.finger;
  out.source = m.source;
  out.seq = m.seq;
  out.utime = m.utime;
  out.times.assign(m.times.begin(), m.times.end());
  out.positions.resize(m.num_points);
  // p_device = R^T (p_scene - origin) for the scene frame (R is a rotation).
  const bool scene = m.frame == hapticloth::trajectory_cmd_t::FRAME_SCENE;
  for (int i = 0; i < m.num_points; ++i) {
    const Eigen::Vector3d p(m.positions[i][0], m.positions[i][1], m.positions[i][2]);
    out.positions[i] = scene ? Eigen::Vector3d(info.device_rotation.transpose() * (p - info.device_origin)) : p;
  }
  return "";
}

}  // namespace hapticloth::transport
