#include "render/renderer.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include <GL/osmesa.h>
#include <GL/gl.h>
#include <Eigen/Geometry>

#include "cloth/cool_warm.hpp"
#include "render/strain.hpp"

namespace hapticloth::render {

namespace {

constexpr double kPi = 3.14159265358979323846;

// Finger colours, by finger index (repeating).
constexpr Rgb kFingerColors[] = {{232, 125, 30}, {30, 150, 175}, {150, 80, 190}, {90, 165, 60}};
constexpr Rgb kArrowColor{215, 30, 35};
constexpr Rgb kTextColor{40, 40, 40};
constexpr Rgb kRefinedEdge{60, 60, 60};

Rgb finger_color(std::size_t f) { return kFingerColors[f % std::size(kFingerColors)]; }

// Triangles with per-corner attributes, as glDrawArrays takes them.
struct Mesh {
  std::vector<float> pos, nrm, col, uv;  // 3, 3, 4, 2 floats per corner
  void clear() { pos.clear(); nrm.clear(); col.clear(); uv.clear(); }
  void corner(const Eigen::Vector3f& p, const Eigen::Vector3f& n, const std::array<float, 4>& c, float u = 0, float v = 0) {
    pos.insert(pos.end(), {p.x(), p.y(), p.z()});
    nrm.insert(nrm.end(), {n.x(), n.y(), n.z()});
    col.insert(col.end(), c.begin(), c.end());
    uv.insert(uv.end(), {u, v});
  }
  GLsizei corners() const { return static_cast<GLsizei>(pos.size() / 3); }
  void draw(bool textured) const {
    if (pos.empty()) return;
    glEnableClientState(GL_VERTEX_ARRAY);
    glEnableClientState(GL_NORMAL_ARRAY);
    glEnableClientState(GL_COLOR_ARRAY);
    glVertexPointer(3, GL_FLOAT, 0, pos.data());
    glNormalPointer(GL_FLOAT, 0, nrm.data());
    glColorPointer(4, GL_FLOAT, 0, col.data());
    if (textured) {
      glEnableClientState(GL_TEXTURE_COORD_ARRAY);
      glTexCoordPointer(2, GL_FLOAT, 0, uv.data());
    }
    glDrawArrays(GL_TRIANGLES, 0, corners());
    glDisableClientState(GL_TEXTURE_COORD_ARRAY);
    glDisableClientState(GL_COLOR_ARRAY);
    glDisableClientState(GL_NORMAL_ARRAY);
    glDisableClientState(GL_VERTEX_ARRAY);
  }
};

std::array<float, 4> rgba(Rgb c, float a = 1.0f) { return {c[0] / 255.0f, c[1] / 255.0f, c[2] / 255.0f, a}; }

void add_sphere(Mesh& m, const Eigen::Vector3f& c, float r, const std::array<float, 4>& col) {
  constexpr int kLat = 16, kLon = 24;
  auto at = [](int i, int j) {
    const double th = kPi * i / kLat, ph = 2 * kPi * j / kLon;
    return Eigen::Vector3f(static_cast<float>(std::sin(th) * std::cos(ph)), static_cast<float>(std::sin(th) * std::sin(ph)),
                           static_cast<float>(std::cos(th)));
  };
  for (int i = 0; i < kLat; ++i)
    for (int j = 0; j < kLon; ++j) {
      const Eigen::Vector3f a = at(i, j), b = at(i + 1, j), d = at(i + 1, j + 1), e = at(i, j + 1);
      for (const Eigen::Vector3f* n : {&a, &b, &d, &a, &d, &e}) m.corner(c + r * *n, *n, col);
    }
}

// An arrow from `base` along `dir` (unit) of total length `len`: a cylinder and a cone.
void add_arrow(Mesh& m, const Eigen::Vector3f& base, const Eigen::Vector3f& dir, float len, float radius,
               const std::array<float, 4>& col) {
  constexpr int kSeg = 16;
  const float head = std::min(len * 0.45f, radius * 5.0f), hr = radius * 2.4f;
  const Eigen::Vector3f a = std::abs(dir.z()) < 0.9f ? Eigen::Vector3f::UnitZ() : Eigen::Vector3f::UnitX();
  const Eigen::Vector3f e1 = dir.cross(a).normalized(), e2 = dir.cross(e1);
  const Eigen::Vector3f neck = base + dir * (len - head), tip = base + dir * len;
  for (int j = 0; j < kSeg; ++j) {
    const double p0 = 2 * kPi * j / kSeg, p1 = 2 * kPi * (j + 1) / kSeg;
    const Eigen::Vector3f n0 = static_cast<float>(std::cos(p0)) * e1 + static_cast<float>(std::sin(p0)) * e2;
    const Eigen::Vector3f n1 = static_cast<float>(std::cos(p1)) * e1 + static_cast<float>(std::sin(p1)) * e2;
    // shaft
    m.corner(base + radius * n0, n0, col);
    m.corner(neck + radius * n0, n0, col);
    m.corner(neck + radius * n1, n1, col);
    m.corner(base + radius * n0, n0, col);
    m.corner(neck + radius * n1, n1, col);
    m.corner(base + radius * n1, n1, col);
    // cone (normals tilted by the cone's half angle) and its base disc
    const float k = hr / head;
    const Eigen::Vector3f c0 = (n0 + k * dir).normalized(), c1 = (n1 + k * dir).normalized();
    m.corner(neck + hr * n0, c0, col);
    m.corner(tip, (c0 + c1).normalized(), col);
    m.corner(neck + hr * n1, c1, col);
    m.corner(neck + hr * n0, -dir, col);
    m.corner(neck + hr * n1, -dir, col);
    m.corner(neck, -dir, col);
  }
}

// The procedural weave: a 3/1 twill (warp on top in three of every four crossings, as in
// denim), indigo warp threads along v, light weft threads along u, each thread shaded across
// its width as a round yarn. One texture repeat is four threads each way.
constexpr int kTex = 256, kThread = kTex / 4;

std::vector<std::uint8_t> weave_texels() {
  const float warp[3] = {62, 92, 158}, weft[3] = {222, 218, 204};
  std::vector<std::uint8_t> t(kTex * kTex * 3);
  for (int y = 0; y < kTex; ++y)
    for (int x = 0; x < kTex; ++x) {
      const int i = x / kThread, j = y / kThread;  // warp thread i (column), weft thread j (row)
      const bool warp_up = (i + j) % 4 != 3;
      const float across = ((warp_up ? x : y) % kThread + 0.5f) / kThread;
      const float along = ((warp_up ? y : x) % kThread + 0.5f) / kThread;
      const float shade = (0.55f + 0.45f * std::sin(static_cast<float>(kPi) * across)) *
                          (0.9f + 0.1f * std::sin(static_cast<float>(kPi) * along));
      const float* c = warp_up ? warp : weft;
      for (int k = 0; k < 3; ++k) t[3 * (y * kTex + x) + k] = static_cast<std::uint8_t>(c[k] * shade);
    }
  return t;
}

// Mipmap levels by 2x2 averaging (no GLU needed).
void upload_mipmaps(std::vector<std::uint8_t> level) {
  int n = kTex;
  for (int l = 0;; ++l) {
    glTexImage2D(GL_TEXTURE_2D, l, GL_RGB, n, n, 0, GL_RGB, GL_UNSIGNED_BYTE, level.data());
    if (n == 1) break;
    const int h = n / 2;
    std::vector<std::uint8_t> next(h * h * 3);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < h; ++x)
        for (int k = 0; k < 3; ++k) {
          const int s = level[3 * ((2 * y) * n + 2 * x) + k] + level[3 * ((2 * y) * n + 2 * x + 1) + k] +
                        level[3 * ((2 * y + 1) * n + 2 * x) + k] + level[3 * ((2 * y + 1) * n + 2 * x + 1) + k];
          next[3 * (y * h + x) + k] = static_cast<std::uint8_t>((s + 2) / 4);
        }
    level = std::move(next);
    n = h;
  }
}

// Area-weighted vertex normals (the cross products are twice the triangle areas).
std::vector<Eigen::Vector3f> vertex_normals(const Scene& s, const std::vector<Vec3f>& x) {
  std::vector<Eigen::Vector3f> n(x.size(), Eigen::Vector3f::Zero());
  for (const auto& t : s.triangles) {
    const Eigen::Vector3f c = (x[t[1]] - x[t[0]]).cross(x[t[2]] - x[t[0]]);
    for (int v : t) n[v] += c;
  }
  for (auto& v : n) {
    const float l = v.norm();
    v = l > 0 ? Eigen::Vector3f(v / l) : Eigen::Vector3f::UnitZ();
  }
  return n;
}

// The corners of `scene`'s triangles at positions x, but those `hidden` (empty: none), as the
// style colours them: per-vertex normals, the weave texture's coordinates or eq. 4's strain.
void add_cloth(Mesh& m, const Scene& scene, const std::vector<Vec3f>& x, const std::vector<bool>& hidden,
               const Style& style) {
  const std::vector<Eigen::Vector3f> n = vertex_normals(scene, x);
  const bool textured = style.color == ColorMode::Weave;
  std::vector<cloth::Strains> eps;
  StrainComponent comp = StrainComponent::Weft;
  if (!textured) {
    comp = style.color == ColorMode::Weft ? StrainComponent::Weft
         : style.color == ColorMode::Warp ? StrainComponent::Warp
                                          : StrainComponent::Shear;
    StrainField(scene).compute(x, eps);
  }
  const float inv_pitch = static_cast<float>(1.0 / style.weave_pitch);
  for (std::size_t i = 0; i < scene.triangles.size(); ++i) {
    if (!hidden.empty() && hidden[i]) continue;
    const auto& t = scene.triangles[i];
    const std::array<float, 4> c =
        textured ? std::array<float, 4>{1, 1, 1, 1} : rgba(diverging_color(component(eps[i], comp) / style.strain_range));
    for (int k = 0; k < 3; ++k)
      m.corner(x[t[k]], n[t[k]], c, scene.weave_uv[i][k][0] * inv_pitch, scene.weave_uv[i][k][1] * inv_pitch);
  }
}

// The edges of a refined child as thin unlit lines, drawn over its surface (depth-tested, so a
// fold in front hides them): where the contact is resolved finer than the global mesh.
void draw_edges(const Scene& mesh, const std::vector<Vec3f>& x, int supersample) {
  glDisable(GL_LIGHTING);
  glLineWidth(static_cast<float>(supersample));  // one pixel of the picture
  glColor3f(kRefinedEdge[0] / 255.0f, kRefinedEdge[1] / 255.0f, kRefinedEdge[2] / 255.0f);
  glBegin(GL_LINES);
  for (const auto& t : mesh.triangles)
    for (int k = 0; k < 3; ++k) {
      const Vec3f& a = x[t[k]];
      const Vec3f& b = x[t[(k + 1) % 3]];
      glVertex3f(a.x(), a.y(), a.z());
      glVertex3f(b.x(), b.y(), b.z());
    }
  glEnd();
  glEnable(GL_LIGHTING);
}

std::string format(const char* fmt, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
}

}  // namespace

bool parse_color_mode(const std::string& s, ColorMode& out) {
  for (ColorMode m : {ColorMode::Weave, ColorMode::Weft, ColorMode::Warp, ColorMode::Shear})
    if (s == color_mode_name(m)) {
      out = m;
      return true;
    }
  return false;
}

const char* color_mode_name(ColorMode m) {
  switch (m) {
    case ColorMode::Weave: return "weave";
    case ColorMode::Weft: return "weft";
    case ColorMode::Warp: return "warp";
    case ColorMode::Shear: return "shear";
  }
  return "?";
}

Rgb diverging_color(double x) {
  const std::array<double, 3> c = cloth::cool_warm(x);
  return {static_cast<std::uint8_t>(std::lround(c[0])), static_cast<std::uint8_t>(std::lround(c[1])),
          static_cast<std::uint8_t>(std::lround(c[2]))};
}

std::vector<Vec3f> framing_points(const ClothFrame& frame, const HapticTick* haptics, const Style& style) {
  std::vector<Vec3f> pts = frame.positions;
  if (style.fingers && haptics) {
    const float r = static_cast<float>(style.finger_radius);
    for (const FingerSample& f : haptics->fingers)
      for (const Vec3f& c : {f.position, f.proxy})
        for (int k = 0; k < 3; ++k) {
          pts.push_back(c + r * Vec3f::Unit(k));
          pts.push_back(c - r * Vec3f::Unit(k));
        }
  }
  return pts;
}

struct Renderer::Impl {
  OSMesaContext ctx = nullptr;
  std::vector<std::uint8_t> buffer;  // RGBA, bottom row first
  GLuint texture = 0;
  Mesh cloth, solid, ghost;
};

Renderer::Renderer(int width, int height, int supersample)
    : width_(width), height_(height), ss_(std::max(1, supersample)), impl_(std::make_unique<Impl>()) {
  if (width < 16 || height < 16 || width > 8192 || height > 8192)
    throw std::runtime_error("picture size " + std::to_string(width) + "x" + std::to_string(height) +
                             " is outside 16..8192 pixels");
  impl_->ctx = OSMesaCreateContextExt(OSMESA_RGBA, 24, 0, 0, nullptr);
  if (!impl_->ctx) throw std::runtime_error("OSMesa: cannot create an offscreen context");
  impl_->buffer.resize(static_cast<std::size_t>(width_ * ss_) * height_ * ss_ * 4);
  if (!OSMesaMakeCurrent(impl_->ctx, impl_->buffer.data(), GL_UNSIGNED_BYTE, width_ * ss_, height_ * ss_)) {
    OSMesaDestroyContext(impl_->ctx);
    throw std::runtime_error("OSMesa: cannot make the context current at " + std::to_string(width_ * ss_) + "x" +
                             std::to_string(height_ * ss_));
  }
  glGenTextures(1, &impl_->texture);
  glBindTexture(GL_TEXTURE_2D, impl_->texture);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  upload_mipmaps(weave_texels());
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_REPEAT);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_REPEAT);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
}

Renderer::~Renderer() {
  if (impl_ && impl_->ctx) OSMesaDestroyContext(impl_->ctx);
}

namespace {
bool shows_colorbar(const Style& s) { return s.colorbar && s.color != ColorMode::Weave; }
int text_scale(int height) { return std::max(1, static_cast<int>(std::lround(height / 330.0))); }
}  // namespace

Viewport Renderer::scene_viewport(const Style& style) const {
  if (!shows_colorbar(style)) return {0, 0, width_, height_};
  const int s = text_scale(height_);
  const int strip = std::min(width_ / 3, std::max(text_width("strain (%)", s), 12 * s + text_width("-10.00", s)) + 8 * s);
  return {0, 0, width_ - strip, height_};
}

Projection Renderer::projection(const Camera& cam, const Style& style, const std::vector<Vec3f>& points) const {
  return make_projection(cam, scene_viewport(style), points);
}

namespace {

constexpr int kLineGap = 4;  // font pixels between text lines

// Time, scene and colour mode, and each finger's force (swatch filled: in contact) at the top
// left, on a light panel so the text stays readable over the cloth.
void draw_label(Image& img, const Scene& scene, const ClothFrame& frame, const HapticTick* haptics,
                const Style& style, int s) {
  struct Line {
    std::string text;
    int finger = -1;
    bool contact = false;
  };
  std::vector<Line> lines;
  lines.push_back({format("t = %.2f s", frame.time)});
  lines.push_back({(scene.name.empty() ? std::string() : scene.name + ", ") + color_mode_name(style.color)});
  if (haptics)
    for (std::size_t f = 0; f < haptics->fingers.size(); ++f) {
      const FingerSample& fs = haptics->fingers[f];
      lines.push_back({"finger " + std::to_string(f) + format("  %.3f N", fs.force.norm()), static_cast<int>(f), fs.contact});
    }
  const int line = text_height(s) + kLineGap * s, box = text_height(s), swatch = box + 3 * s;
  int w = 0;
  for (const Line& l : lines) w = std::max(w, text_width(l.text, s) + (l.finger >= 0 ? swatch : 0));
  fill_rect(img, 0, 0, w + 9 * s, static_cast<int>(lines.size()) * line + 5 * s, style.background, 0.75);
  int y = 4 * s;
  for (const Line& l : lines) {
    int x = 5 * s;
    if (l.finger >= 0) {
      const Rgb c = finger_color(static_cast<std::size_t>(l.finger));
      fill_rect(img, x, y, x + box, y + box, c);
      if (!l.contact) fill_rect(img, x + s, y + s, x + box - s, y + box - s, style.background);
      x += swatch;
    }
    draw_text(img, x, y, l.text, s, kTextColor);
    y += line;
  }
}

// The colour bar in the strip right of x0: title, bar from +range (top) to -range, five labels.
void draw_colorbar(Image& img, int x0, const Style& style, int s) {
  const int line = text_height(s) + kLineGap * s;
  const int top = 8 * s + 2 * line, bottom = img.height - 10 * s, bar = 8 * s;
  draw_text(img, x0, 6 * s, color_mode_name(style.color), s, kTextColor);
  draw_text(img, x0, 6 * s + line, "strain (%)", s, kTextColor);
  for (int y = top; y < bottom; ++y) {
    const double v = 1.0 - 2.0 * (y - top + 0.5) / (bottom - top);
    fill_rect(img, x0, y, x0 + bar, y + 1, diverging_color(v));
  }
  const double pct = 100.0 * style.strain_range;
  const char* fmt = pct < 0.1 ? "%+.3f" : pct < 1 ? "%+.2f" : pct < 10 ? "%+.1f" : "%+.0f";
  for (int k = 0; k <= 4; ++k) {
    const int y = top + static_cast<int>(std::lround((bottom - top - 1) * 0.25 * k));
    fill_rect(img, x0, y, x0 + bar, y + std::max(1, s / 2), kTextColor);  // the tick, across the bar
    const std::string t = k == 2 ? std::string("0") : format(fmt, (1.0 - 0.5 * k) * pct);
    draw_text(img, x0 + bar + 4 * s, std::clamp(y - text_height(s) / 2, 0, img.height - text_height(s)), t, s,
              kTextColor);
  }
}

// Lights in eye space: a key light from the upper left, a weaker fill from the right; then the
// view, and a material with a little specular shine.
void set_lights(const Projection& P) {
  glMatrixMode(GL_MODELVIEW);
  glLoadIdentity();
  const GLfloat key_dir[] = {-0.45f, 0.6f, 0.75f, 0.0f}, fill_dir[] = {0.7f, -0.2f, 0.5f, 0.0f};
  const GLfloat key[] = {0.72f, 0.72f, 0.7f, 1.0f}, fill[] = {0.25f, 0.25f, 0.27f, 1.0f};
  const GLfloat spec[] = {0.12f, 0.12f, 0.12f, 1.0f}, none[] = {0, 0, 0, 1}, ambient[] = {0.3f, 0.3f, 0.3f, 1.0f};
  glEnable(GL_LIGHTING);
  glLightModeli(GL_LIGHT_MODEL_TWO_SIDE, GL_TRUE);
  glLightModelfv(GL_LIGHT_MODEL_AMBIENT, ambient);
  glEnable(GL_LIGHT0);
  glLightfv(GL_LIGHT0, GL_POSITION, key_dir);
  glLightfv(GL_LIGHT0, GL_DIFFUSE, key);
  glLightfv(GL_LIGHT0, GL_SPECULAR, spec);
  glEnable(GL_LIGHT1);
  glLightfv(GL_LIGHT1, GL_POSITION, fill_dir);
  glLightfv(GL_LIGHT1, GL_DIFFUSE, fill);
  glLightfv(GL_LIGHT1, GL_SPECULAR, none);
  glLoadMatrixd(P.view.data());
  glEnable(GL_NORMALIZE);
  glEnable(GL_COLOR_MATERIAL);
  glColorMaterial(GL_FRONT_AND_BACK, GL_AMBIENT_AND_DIFFUSE);
  const GLfloat white[] = {1, 1, 1, 1};
  glMaterialfv(GL_FRONT_AND_BACK, GL_SPECULAR, white);
  glMaterialf(GL_FRONT_AND_BACK, GL_SHININESS, 24.0f);
}

// The global triangles a refined child stands in for, not drawn.
std::vector<bool> hidden_triangles(const Scene& scene, const RefinedFrame& refined) {
  std::vector<bool> hidden(scene.triangles.size(), false);
  for (const int t : refined.region) {
    if (t < 0 || static_cast<std::size_t>(t) >= hidden.size())
      throw std::invalid_argument("refined region names triangle " + std::to_string(t) + ", the mesh has " +
                                  std::to_string(hidden.size()));
    hidden[t] = true;
  }
  return hidden;
}

// The springs between proxies and device positions: unlit lines.
void draw_springs(const HapticTick& haptics, int ss) {
  glDisable(GL_LIGHTING);
  glLineWidth(static_cast<float>(ss));
  glBegin(GL_LINES);
  for (const FingerSample& s : haptics.fingers) {
    glColor3f(0.25f, 0.25f, 0.25f);
    glVertex3f(s.proxy.x(), s.proxy.y(), s.proxy.z());
    glVertex3f(s.position.x(), s.position.y(), s.position.z());
  }
  glEnd();
  glEnable(GL_LIGHTING);
}

}  // namespace

// The viewport, cleared, with the projection of `P`.
void Renderer::begin_frame(const Projection& P, const Style& style) {
  const Viewport& vp = P.viewport;
  glViewport(vp.x * ss_, (height_ - vp.y - vp.height) * ss_, vp.width * ss_, vp.height * ss_);
  glClearColor(style.background[0] / 255.0f, style.background[1] / 255.0f, style.background[2] / 255.0f, 1.0f);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  glEnable(GL_DEPTH_TEST);
  glDepthMask(GL_TRUE);
  glDisable(GL_CULL_FACE);
  glShadeModel(GL_SMOOTH);
  glMatrixMode(GL_PROJECTION);
  glLoadMatrixd(P.proj.data());
}

// The cloth: per-vertex normals, per-triangle colour or the weave texture; the refined children
// under the fingertips in place of the global triangles they stand in for.
void Renderer::draw_cloth(const Scene& scene, const ClothFrame& frame, const Style& style) {
  Impl& im = *impl_;
  const bool textured = style.color == ColorMode::Weave;
  const RefinedFrame& refined = frame.refined;
  im.cloth.clear();
  add_cloth(im.cloth, scene, frame.positions, hidden_triangles(scene, refined), style);
  if (!refined.empty()) add_cloth(im.cloth, refined.mesh, refined.positions, {}, style);
  if (textured) {
    glEnable(GL_TEXTURE_2D);
    glBindTexture(GL_TEXTURE_2D, im.texture);
    glTexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GL_MODULATE);
  }
  // Pull the cloth slightly back in depth so the fingertips' contact spots win ties.
  glEnable(GL_POLYGON_OFFSET_FILL);
  glPolygonOffset(1.0f, 1.0f);
  im.cloth.draw(textured);
  glDisable(GL_POLYGON_OFFSET_FILL);
  glDisable(GL_TEXTURE_2D);
  if (style.refined_edges && !refined.empty()) draw_edges(refined.mesh, refined.positions, ss_);
}

// The fingertips: the proxy solid, the device position as a translucent ghost, the spring
// between them and the force on the finger as an arrow from the proxy.
void Renderer::draw_fingertips(const HapticTick& haptics, const Style& style) {
  Impl& im = *impl_;
  im.solid.clear();
  im.ghost.clear();
  const float r = static_cast<float>(style.finger_radius);
  for (std::size_t f = 0; f < haptics.fingers.size(); ++f) {
    const FingerSample& s = haptics.fingers[f];
    add_sphere(im.solid, s.proxy, r, rgba(finger_color(f)));
    add_sphere(im.ghost, s.position, r, rgba(finger_color(f), 0.35f));
    const float fl = s.force.norm(), len = static_cast<float>(style.force_scale) * fl;
    if (len > 0.3f * r) {
      const Eigen::Vector3f dir = s.force / fl;
      add_arrow(im.solid, s.proxy + dir * r, dir, len, 0.25f * r, rgba(kArrowColor));
    }
  }
  im.solid.draw(false);
  draw_springs(haptics, ss_);
  glEnable(GL_BLEND);
  glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
  glDepthMask(GL_FALSE);
  im.ghost.draw(false);
  glDepthMask(GL_TRUE);
  glDisable(GL_BLEND);
}

// The picture (OSMesa rows are bottom-up), the supersamples averaged.
Image Renderer::read_back() const {
  const int W = width_ * ss_, H = height_ * ss_;
  Image big(W, H);
  for (int y = 0; y < H; ++y) {
    const std::uint8_t* src = &impl_->buffer[static_cast<std::size_t>(H - 1 - y) * W * 4];
    std::uint8_t* dst = &big.rgb[static_cast<std::size_t>(y) * W * 3];
    for (int xx = 0; xx < W; ++xx)
      for (int k = 0; k < 3; ++k) dst[3 * xx + k] = src[4 * xx + k];
  }
  return downsample(big, ss_);
}

Image Renderer::render(const Scene& scene, const ClothFrame& frame, const HapticTick* haptics, const Camera& cam,
                       const Style& style) {
  if (!OSMesaMakeCurrent(impl_->ctx, impl_->buffer.data(), GL_UNSIGNED_BYTE, width_ * ss_, height_ * ss_))
    throw std::runtime_error("OSMesa: cannot make the context current");
  if (frame.positions.size() != scene.rest_positions.size())
    throw std::invalid_argument("cloth state has " + std::to_string(frame.positions.size()) +
                                " vertices, the mesh " + std::to_string(scene.rest_positions.size()));
  const bool draw_fingers = style.fingers && haptics;
  const Projection P = projection(cam, style, framing_points(frame, haptics, style));
  const Viewport& vp = P.viewport;
  begin_frame(P, style);
  set_lights(P);
  draw_cloth(scene, frame, style);
  if (draw_fingers) draw_fingertips(*haptics, style);
  glFinish();
  Image img = read_back();
  // Outside the viewport (the colour bar's strip) glClear did not reach: paint it.
  fill_rect(img, vp.x + vp.width, 0, width_, height_, style.background);
  const int s = text_scale(height_);
  if (style.label) draw_label(img, scene, frame, draw_fingers ? haptics : nullptr, style, s);
  if (shows_colorbar(style)) draw_colorbar(img, vp.x + vp.width + 4 * s, style, s);
  return img;
}

}  // namespace hapticloth::render
