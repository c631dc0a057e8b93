// Tests of hapticloth-render (clients/render): the log reader, the strain colours, the
// silhouette of the drawn cloth against the projection of its mesh, the PNG encoder and the
// program's errors for logs it cannot use.
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

namespace {

using namespace hapticloth::render;
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
Scene hanging() {
  return grid(16, 16, 0.4, 0.3, [](double u, double v) {
    return Vec3f(static_cast<float>(u - 0.2), static_cast<float>(0.03 * std::sin(3.14159 * u / 0.4) * std::sin(3.14159 * v / 0.3)),
                 static_cast<float>(v - 0.3));
  });
}

// Flat cloth in the xy plane: u along x, v along y.
Scene flat() {
  return grid(12, 12, 0.3, 0.3, [](double u, double v) { return Vec3f(static_cast<float>(u), static_cast<float>(v), 0.0f); });
}

ClothFrame rest_frame(const Scene& s, double time = 0.0) {
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
Box silhouette(const Image& img, Rgb bg, const Viewport& vp) {
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
std::array<double, 3> mean_cloth_color(const Image& img, Rgb bg) {
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
void expect_silhouette_matches(const Renderer& r, const Image& img, const ClothFrame& f, const Camera& cam,
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

Style bare_style() {
  Style st;
  st.label = false;
  st.fingers = false;
  st.colorbar = false;
  return st;
}

TEST(Render, SilhouetteMatchesProjectedMeshBoxWithDefaultFraming) {
  const Scene s = hanging();
  const ClothFrame f = rest_frame(s);
  Renderer r(320, 240, 2);
  Style st = bare_style();
  const Viewport vp = r.scene_viewport(st);
  const Camera cam = frame_points(f.positions, 35.0, static_cast<double>(vp.width) / vp.height);
  const Image img = r.render(s, f, nullptr, cam, st);
  ASSERT_EQ(img.width, 320);
  ASSERT_EQ(img.height, 240);
  const Box b = silhouette(img, st.background, vp);
  // Non-empty, and the default framing fills the frame along one axis at least to 80%.
  EXPECT_GT(b.count, 320 * 240 / 10);
  EXPECT_TRUE(b.x1 - b.x0 > 0.8 * 320 || b.y1 - b.y0 > 0.8 * 240) << b.x0 << " " << b.x1 << " " << b.y0 << " " << b.y1;
  expect_silhouette_matches(r, img, f, cam, st, 2.0);
}

TEST(Render, SilhouetteMatchesProjectedMeshBoxWithGivenCameraAndColourBar) {
  const Scene s = hanging();
  const ClothFrame f = rest_frame(s);
  Renderer r(400, 300, 2);
  Style st = bare_style();
  st.color = ColorMode::Shear;
  st.colorbar = true;
  st.background = {10, 10, 20};  // the light grey of zero strain must not pass for background
  Camera cam;
  cam.eye = {0.35, -0.7, 0.1};
  cam.target = {0.0, 0.0, -0.15};
  cam.fov_deg = 40;
  const Image img = r.render(s, f, nullptr, cam, st);
  const Viewport vp = r.scene_viewport(st);
  EXPECT_LT(vp.width, 400);  // the colour bar's strip
  expect_silhouette_matches(r, img, f, cam, st, 2.0);
}

TEST(Strain, UniformStretchGivesThatWeftStrain) {
  const Scene s = flat();
  ClothFrame f = rest_frame(s);
  for (auto& p : f.positions) p.x() *= 1.03f;
  std::vector<hapticloth::cloth::Strains> eps;
  StrainField(s).compute(f.positions, eps);
  ASSERT_EQ(eps.size(), s.triangles.size());
  for (const auto& e : eps) {
    EXPECT_NEAR(e.uu, 0.03, 1e-6);
    EXPECT_NEAR(e.vv, 0.0, 1e-6);
    EXPECT_NEAR(e.uv, 0.0, 1e-6);
  }
}

TEST(Render, StrainColoursChangeWhenTheClothIsStretched) {
  const Scene s = flat();
  const ClothFrame rest = rest_frame(s);
  ClothFrame stretched = rest, compressed = rest;
  for (auto& p : stretched.positions) p.x() *= 1.03f;
  for (auto& p : compressed.positions) p.x() *= 0.97f;
  Renderer r(240, 180, 1);
  Style st = bare_style();
  st.color = ColorMode::Weft;
  st.strain_range = 0.05;
  st.background = {0, 0, 0};
  const Viewport vp = r.scene_viewport(st);
  const Camera cam = frame_points(stretched.positions, 35.0, static_cast<double>(vp.width) / vp.height);
  const auto m0 = mean_cloth_color(r.render(s, rest, nullptr, cam, st), st.background);
  const auto m1 = mean_cloth_color(r.render(s, stretched, nullptr, cam, st), st.background);
  const auto m2 = mean_cloth_color(r.render(s, compressed, nullptr, cam, st), st.background);
  // At rest the map's middle (grey: red ~ blue); stretched it turns red, compressed blue.
  EXPECT_LT(std::abs(m0[0] - m0[2]), 15.0);
  EXPECT_GT((m1[0] - m1[2]) - (m0[0] - m0[2]), 40.0) << m1[0] << " " << m1[2];
  EXPECT_GT((m2[2] - m2[0]) - (m0[2] - m0[0]), 40.0) << m2[0] << " " << m2[2];
  // The warp colours do not see a weft stretch.
  st.color = ColorMode::Warp;
  const auto w1 = mean_cloth_color(r.render(s, stretched, nullptr, cam, st), st.background);
  EXPECT_LT(std::abs(w1[0] - w1[2]), 15.0);
}

TEST(Render, FingertipIsDrawnWhereItProjects) {
  const Scene s = hanging();
  const ClothFrame f = rest_frame(s);
  HapticTick h;
  h.time = 0.0;
  FingerSample fs;
  fs.position = fs.proxy = Vec3f(0.0f, -0.05f, -0.15f);  // in front of the cloth
  fs.force = Vec3f(0.0f, -2.0f, 0.0f);
  h.fingers.push_back(fs);
  Renderer r(320, 240, 2);
  Style st = bare_style();
  st.fingers = true;
  const Viewport vp = r.scene_viewport(st);
  const Camera cam = frame_points(framing_points(f, &h, st), 35.0, static_cast<double>(vp.width) / vp.height);
  const Image img = r.render(s, f, &h, cam, st);
  const Eigen::Vector2d c = r.projection(cam, st, framing_points(f, &h, st)).to_pixel(fs.proxy.cast<double>());
  const Rgb px = img.at(static_cast<int>(c.x()), static_cast<int>(c.y()));
  // Finger 0 is orange: red > green > blue, unlike the blue weave behind it.
  EXPECT_GT(px[0], px[1]);
  EXPECT_GT(px[1], px[2]);
  EXPECT_GT(px[0], 120);
}

// --- PNG -------------------------------------------------------------------------------------

std::vector<std::uint8_t> read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::uint32_t be32(const std::uint8_t* p) { return (p[0] << 24) | (p[1] << 16) | (p[2] << 8) | p[3]; }

// A decoder for what write_png writes (8-bit RGB, one or more IDAT chunks).
Image decode_png(const std::vector<std::uint8_t>& f) {
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

TEST(Png, RoundTripsARenderedImage) {
  const Scene s = hanging();
  Renderer r(200, 150, 1);
  Style st;
  st.color = ColorMode::Shear;
  const ClothFrame f = rest_frame(s, 1.25);
  const Image img = r.render(s, f, nullptr, frame_points(f.positions, 35.0, 1.2), st);
  const std::string path = (fs::temp_directory_path() / "hapticloth_test_render.png").string();
  write_png(path, img);
  const auto bytes = read_bytes(path);
  ASSERT_GT(bytes.size(), 33u);
  EXPECT_EQ(std::string(reinterpret_cast<const char*>(bytes.data()) + 1, 3), "PNG");
  const Image back = decode_png(bytes);
  EXPECT_EQ(back.width, 200);
  EXPECT_EQ(back.height, 150);
  EXPECT_EQ(back.rgb, img.rgb);
  fs::remove(path);
  EXPECT_THROW(write_png("/nonexistent-dir/x.png", img), std::runtime_error);
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

hapticloth::cloth_topology_t topology_msg(const Scene& s) {
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

hapticloth::cloth_state_t state_msg(const Scene& s, double time, float stretch) {
  hapticloth::cloth_state_t m;
  m.time = time;
  m.step = std::lround(time * 1000);
  m.num_vertices = static_cast<int>(s.rest_positions.size());
  for (const Vec3f& p : s.rest_positions) m.positions.push_back({p.x() * stretch, p.y(), p.z()});
  return m;
}

hapticloth::haptic_state_t haptic_msg(double t0, int n, int fingers) {
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

std::string temp_path(const std::string& name) { return (fs::temp_directory_path() / name).string(); }

TEST(Log, ReadsTopologyStatesAndHapticsWhateverTheChannel) {
  const Scene s = flat();
  const std::string path = temp_path("hapticloth_test_render_ok.lcm");
  {
    LogWriter w(path);
    w.write("SOME_OTHER_NAME", topology_msg(s));
    w.write("HAPTICLOTH_CLOTH", state_msg(s, 0.2, 1.0f));
    w.write("HAPTICLOTH_CLOTH", state_msg(s, 0.1, 1.0f));  // out of order
    w.write("HAPTICLOTH_CLOTH", state_msg(s, 0.3, 1.02f));
    hapticloth::cloth_state_t wrong = state_msg(s, 0.4, 1.0f);
    wrong.num_vertices = 3;
    wrong.positions.resize(3);
    w.write("HAPTICLOTH_CLOTH", wrong);
    w.write("HAPTICLOTH_HAPTICS", haptic_msg(0.1, 5, 2));
    w.write("HAPTICLOTH_HAPTICS", haptic_msg(0.2, 5, 2));
  }
  const Recording rec = read_lcm_log(path);
  ASSERT_EQ(rec.scene.triangles.size(), s.triangles.size());
  ASSERT_EQ(rec.frames.size(), 3u);
  EXPECT_EQ(rec.dropped, 1u);
  EXPECT_DOUBLE_EQ(rec.frames[0].time, 0.1);
  EXPECT_DOUBLE_EQ(rec.frames[2].time, 0.3);
  EXPECT_EQ(rec.frame_near(0.26), 2u);
  EXPECT_EQ(rec.frame_near(0.24), 1u);
  EXPECT_EQ(rec.frame_near(99.0), 2u);
  ASSERT_EQ(rec.haptics.size(), 10u);
  const HapticTick* h = rec.haptics_at(0.2035);
  ASSERT_NE(h, nullptr);
  EXPECT_DOUBLE_EQ(h->time, 0.203);
  ASSERT_EQ(h->fingers.size(), 2u);
  EXPECT_FLOAT_EQ(h->fingers[1].position.x(), 0.1f);
  EXPECT_FLOAT_EQ(h->fingers[0].force.y(), -3.0f);
  EXPECT_TRUE(h->fingers[0].contact);
  EXPECT_EQ(rec.haptics_at(0.0), &rec.haptics.front());
  fs::remove(path);
}

TEST(Log, MissingTopologyIsAClearError) {
  const Scene s = flat();
  const std::string path = temp_path("hapticloth_test_render_notopo.lcm");
  {
    LogWriter w(path);
    w.write("HAPTICLOTH_CLOTH", state_msg(s, 0.1, 1.0f));
  }
  try {
    read_lcm_log(path);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), path + ": no cloth_topology_t message (was the log written by hapticloth-server?)");
  }
  EXPECT_THROW(read_lcm_log(temp_path("hapticloth_no_such_log.lcm")), InputError);
  fs::remove(path);
}

// --- the program -------------------------------------------------------------------------------

struct RunResult {
  int code = -1;
  std::string out;
};

RunResult run_render(const std::string& args) {
  const std::string err = temp_path("hapticloth_test_render.err");
  const std::string cmd = std::string(HAPTICLOTH_RENDER_EXE) + " " + args + " >" + err + " 2>&1";
  const int st = std::system(cmd.c_str());
  RunResult r;
  r.code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  const auto bytes = read_bytes(err);
  r.out.assign(bytes.begin(), bytes.end());
  fs::remove(err);
  return r;
}

TEST(Program, LogWithoutTopologyExitsWithCode2AndSaysWhy) {
  const Scene s = flat();
  const std::string path = temp_path("hapticloth_test_render_cli_notopo.lcm");
  {
    LogWriter w(path);
    w.write("HAPTICLOTH_CLOTH", state_msg(s, 0.1, 1.0f));
  }
  const RunResult r = run_render("--log " + path + " --snapshot " + temp_path("hapticloth_unused.png"));
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find(path + ": no cloth_topology_t message (was the log written by hapticloth-server?)"),
            std::string::npos)
      << r.out;
  fs::remove(path);

  const RunResult missing = run_render("--log " + temp_path("hapticloth_no_such_log.lcm") + " --snapshot " +
                                 temp_path("hapticloth_unused.png"));
  EXPECT_EQ(missing.code, 2) << missing.out;
  EXPECT_NE(missing.out.find("cannot open"), std::string::npos) << missing.out;
}

TEST(Program, SnapshotAndFramesFromALog) {
  const Scene s = flat();
  const std::string path = temp_path("hapticloth_test_render_cli.lcm");
  {
    LogWriter w(path);
    w.write("HAPTICLOTH_TOPOLOGY", topology_msg(s));
    for (int k = 0; k < 6; ++k) w.write("HAPTICLOTH_CLOTH", state_msg(s, 0.1 * k, 1.0f + 0.005f * k));
    w.write("HAPTICLOTH_HAPTICS", haptic_msg(0.0, 600, 2));
  }
  const std::string png = temp_path("hapticloth_test_render_snap.png");
  RunResult r = run_render("--log " + path + " --snapshot " + png + " --time 0.31 --size 300x200 --color weft");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("t = 0.3 s"), std::string::npos) << r.out;
  const Image img = decode_png(read_bytes(png));
  EXPECT_EQ(img.width, 300);
  EXPECT_EQ(img.height, 200);

  const std::string dir = temp_path("hapticloth_test_render_frames");
  fs::remove_all(dir);
  r = run_render("--log " + path + " --frames " + dir + " --fps 20 --size 160x120 --supersample 1");
  ASSERT_EQ(r.code, 0) << r.out;
  // 0 .. 0.5 s at 20 fps: 11 frames.
  EXPECT_TRUE(fs::exists(fs::path(dir) / "frame_00010.png"));
  EXPECT_FALSE(fs::exists(fs::path(dir) / "frame_00011.png"));
  fs::remove_all(dir);
  fs::remove(png);
  fs::remove(path);

  // Usage errors exit 2, the option named.
  EXPECT_EQ(run_render("--log " + path + " --snapshot x.png --size 12by5").code, 2);
  EXPECT_EQ(run_render("--log " + path + " --snapshot x.png --color plaid").code, 2);
}

}  // namespace
