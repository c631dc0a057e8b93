// What the tests of the renderer client (clients/render) share: cloth scenes and their rest
// frames, the drawn silhouette and colours of an image, a PNG decoder, and an LCM log writer
// with the server's messages.
#pragma once

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>
#include <zlib.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <lcm/eventlog.h>

#include "hapticloth/cloth_state_t.hpp"
#include "hapticloth/cloth_topology_t.hpp"
#include "hapticloth/haptic_state_t.hpp"
#include "render/image.hpp"
#include "render/recording.hpp"
#include "render/renderer.hpp"
#include "render/strain.hpp"

namespace hapticloth::render::test {

namespace fs = std::filesystem;

// A rectangular cloth of nx x ny quads, size a (weft, u) x b (warp, v) in metres, with its
// rest shape mapped into the scene by `place(u, v)`.
template <class F>
Scene grid(int nx, int ny, double a, double b, F place) {
  Scene s;
  s.name = "grid";
  for (int j = 0; j <= ny; ++j)
    for (int i = 0; i <= nx; ++i) s.rest_positions.push_back(place(a * i / nx, b * j / ny));
  auto id = [&](int i, int j) { return j * (nx + 1) + i; };
  auto uv = [&](int v) -> std::array<float, 2> {
    return {static_cast<float>(a * (v % (nx + 1)) / nx), static_cast<float>(b * (v / (nx + 1)) / ny)};
  };
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i)
      for (const std::array<int, 3>& t : {std::array<int, 3>{id(i, j), id(i + 1, j), id(i + 1, j + 1)},
                                          std::array<int, 3>{id(i, j), id(i + 1, j + 1), id(i, j + 1)}}) {
        s.triangles.push_back(t);
        s.weave_uv.push_back({uv(t[0]), uv(t[1]), uv(t[2])});
      }
  return s;
}

// Vertical cloth in the xz plane, bulging along y (a hanging cloth, pushed).
inline Scene hanging() {
  return grid(16, 16, 0.4, 0.3, [](double u, double v) {
    return Vec3f(static_cast<float>(u - 0.2), static_cast<float>(0.03 * std::sin(3.14159 * u / 0.4) * std::sin(3.14159 * v / 0.3)),
                 static_cast<float>(v - 0.3));
  });
}

// Flat cloth in the xy plane: u along x, v along y.
inline Scene flat() {
  return grid(12, 12, 0.3, 0.3, [](double u, double v) { return Vec3f(static_cast<float>(u), static_cast<float>(v), 0.0f); });
}

inline ClothFrame rest_frame(const Scene& s, double time = 0.0) {
  ClothFrame f;
  f.time = time;
  f.positions = s.rest_positions;
  return f;
}

struct Box {
  int x0 = 1 << 30, y0 = 1 << 30, x1 = -1, y1 = -1;  // inclusive pixel indices
  long count = 0;
};

// Pixels that differ from the background (inside the viewport).
inline Box silhouette(const Image& img, Rgb bg, const Viewport& vp) {
  Box b;
  for (int y = vp.y; y < vp.y + vp.height; ++y)
    for (int x = vp.x; x < vp.x + vp.width; ++x) {
      const Rgb c = img.at(x, y);
      const int d = std::abs(c[0] - bg[0]) + std::abs(c[1] - bg[1]) + std::abs(c[2] - bg[2]);
      if (d <= 24) continue;
      ++b.count;
      b.x0 = std::min(b.x0, x);
      b.y0 = std::min(b.y0, y);
      b.x1 = std::max(b.x1, x);
      b.y1 = std::max(b.y1, y);
    }
  return b;
}

// Mean colour of the pixels that differ from the background.
inline std::array<double, 3> mean_cloth_color(const Image& img, Rgb bg) {
  std::array<double, 3> sum{0, 0, 0};
  long n = 0;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      const Rgb c = img.at(x, y);
      if (std::abs(c[0] - bg[0]) + std::abs(c[1] - bg[1]) + std::abs(c[2] - bg[2]) <= 24) continue;
      for (int k = 0; k < 3; ++k) sum[k] += c[k];
      ++n;
    }
  for (auto& v : sum) v /= std::max(1L, n);
  return sum;
}

// The projected mesh's pixel box must match the drawn silhouette within `tol` pixels.
inline void expect_silhouette_matches(const Renderer& r, const Image& img, const ClothFrame& f, const Camera& cam,
                               const Style& st, double tol) {
  const Projection P = r.projection(cam, st, f.positions);
  double px0 = 1e9, py0 = 1e9, px1 = -1e9, py1 = -1e9;
  for (const Vec3f& p : f.positions) {
    const Eigen::Vector2d q = P.to_pixel(p.cast<double>());
    px0 = std::min(px0, q.x());
    py0 = std::min(py0, q.y());
    px1 = std::max(px1, q.x());
    py1 = std::max(py1, q.y());
  }
  const Box b = silhouette(img, st.background, P.viewport);
  ASSERT_GT(b.count, 0) << "nothing drawn";
  // The cloth covers a good part of the frame (default framing) and the silhouette's box is the
  // projected mesh's box: pixel [x0, x1] covers [x0, x1 + 1).
  EXPECT_NEAR(b.x0, px0, tol);
  EXPECT_NEAR(b.y0, py0, tol);
  EXPECT_NEAR(b.x1 + 1, px1, tol);
  EXPECT_NEAR(b.y1 + 1, py1, tol);
}

inline Style bare_style() {
  Style st;
  st.label = false;
  st.fingers = false;
  st.colorbar = false;
  return st;
}

// --- PNG -------------------------------------------------------------------------------------

inline std::vector<std::uint8_t> read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

inline std::uint32_t be32(const std::uint8_t* p) { return (p[0] << 24) | (p[1] << 16) | (p[2] << 8) | p[3]; }

// A decoder for what write_png writes (8-bit RGB, one or more IDAT chunks).
inline Image decode_png(const std::vector<std::uint8_t>& f) {
  Image img;
  std::vector<std::uint8_t> z;
  for (std::size_t at = 8; at + 12 <= f.size();) {
    const std::uint32_t len = be32(&f[at]);
    const std::string type(reinterpret_cast<const char*>(&f[at + 4]), 4);
    const std::uint8_t* d = &f[at + 8];
    EXPECT_EQ(crc32(0L, &f[at + 4], len + 4), be32(d + len)) << type;
    if (type == "IHDR") img = Image(static_cast<int>(be32(d)), static_cast<int>(be32(d + 4)));
    if (type == "IDAT") z.insert(z.end(), d, d + len);
    at += 12 + len;
  }
  const int stride = 3 * img.width;
  std::vector<std::uint8_t> raw(static_cast<std::size_t>(stride + 1) * img.height);
  uLongf n = raw.size();
  EXPECT_EQ(uncompress(raw.data(), &n, z.data(), z.size()), Z_OK);
  for (int y = 0; y < img.height; ++y) {
    const std::uint8_t type = raw[y * (stride + 1)];
    const std::uint8_t* in = &raw[y * (stride + 1) + 1];
    std::uint8_t* out = &img.rgb[y * stride];
    const std::uint8_t* up = y > 0 ? &img.rgb[(y - 1) * stride] : nullptr;
    for (int i = 0; i < stride; ++i) {
      const int a = i >= 3 ? out[i - 3] : 0, b = up ? up[i] : 0, c = (up && i >= 3) ? up[i - 3] : 0;
      const int p = a + b - c, pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
      const int pred = type == 0 ? 0 : type == 1 ? a : type == 2 ? b : type == 3 ? (a + b) / 2
                     : (pa <= pb && pa <= pc ? a : pb <= pc ? b : c);
      out[i] = static_cast<std::uint8_t>(in[i] + pred);
    }
  }
  return img;
}


// --- logs ------------------------------------------------------------------------------------

class LogWriter {
 public:
  explicit LogWriter(const std::string& path) : log_(lcm_eventlog_create(path.c_str(), "w")) {}
  ~LogWriter() { lcm_eventlog_destroy(log_); }
  template <class M>
  void write(const std::string& channel, const M& m) {
    std::vector<std::uint8_t> buf(m.getEncodedSize());
    m.encode(buf.data(), 0, static_cast<int>(buf.size()));
    lcm_eventlog_event_t ev{};
    ev.timestamp = ++utime_;
    ev.channellen = static_cast<std::int32_t>(channel.size());
    ev.datalen = static_cast<std::int32_t>(buf.size());
    ev.channel = const_cast<char*>(channel.c_str());
    ev.data = buf.data();
    ASSERT_EQ(lcm_eventlog_write_event(log_, &ev), 0);
  }

 private:
  lcm_eventlog_t* log_;
  std::int64_t utime_ = 1000;
};

inline hapticloth::cloth_topology_t topology_msg(const Scene& s) {
  hapticloth::cloth_topology_t m;
  m.num_vertices = static_cast<int>(s.rest_positions.size());
  m.num_triangles = static_cast<int>(s.triangles.size());
  for (std::size_t i = 0; i < s.triangles.size(); ++i) {
    m.triangles.push_back({s.triangles[i][0], s.triangles[i][1], s.triangles[i][2]});
    m.weave_uv.push_back({{s.weave_uv[i][0][0], s.weave_uv[i][0][1]},
                          {s.weave_uv[i][1][0], s.weave_uv[i][1][1]},
                          {s.weave_uv[i][2][0], s.weave_uv[i][2][1]}});
  }
  for (const Vec3f& p : s.rest_positions) m.rest_positions.push_back({p.x(), p.y(), p.z()});
  return m;
}

inline hapticloth::cloth_state_t state_msg(const Scene& s, double time, float stretch) {
  hapticloth::cloth_state_t m{};
  m.time = time;
  m.step = std::lround(time * 1000);
  m.num_vertices = static_cast<int>(s.rest_positions.size());
  for (const Vec3f& p : s.rest_positions) m.positions.push_back({p.x() * stretch, p.y(), p.z()});
  return m;
}

inline hapticloth::haptic_state_t haptic_msg(double t0, int n, int fingers) {
  hapticloth::haptic_state_t m;
  m.num_samples = n;
  m.num_fingers = fingers;
  for (int k = 0; k < n; ++k) {
    m.time.push_back(t0 + k * 0.001);
    m.tick.push_back(std::lround((t0 + k * 0.001) * 1000) + 1);
    std::vector<std::vector<float>> p, f;
    std::vector<std::int8_t> c;
    for (int j = 0; j < fingers; ++j) {
      p.push_back({0.1f * j, -0.02f, 0.0f});
      f.push_back({0.0f, -static_cast<float>(k), 0.0f});
      c.push_back(k > 0);
    }
    m.device_position.push_back(p);
    m.position.push_back(p);
    m.proxy.push_back(p);
    m.force.push_back(f);
    m.command.push_back(f);
    m.in_contact.push_back(c);
    m.slipping.push_back(std::vector<std::int8_t>(fingers, 0));
    m.command_flags.push_back(0);
  }
  return m;
}

inline std::string temp_path(const std::string& name) { return (fs::temp_directory_path() / name).string(); }


}  // namespace hapticloth::render::test
