// The renderer (clients/render/renderer): the silhouette of the drawn cloth against the
// projection of its mesh, the strain colours of a stretched cloth, the fingertip where it projects.
#include <gtest/gtest.h>

#include "render_fixtures.hpp"

namespace {

using namespace hapticloth::render;
using namespace hapticloth::render::test;

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


// A refined child (paper 4.2.2) of flat()'s quad (5, 5): a 2 x 2-quad grid over the quad's
// rest square, placed by `place` from its rest point; it stands in for the quad's two triangles.
template <class F>
RefinedFrame child_of_quad(const Scene& s, F place) {
  const float h = 0.3f / 12, x0 = 5 * h, y0 = 5 * h;
  RefinedFrame r;
  r.mesh = grid(2, 2, h, h, [&](double u, double v) { return place(Vec3f(x0 + float(u), y0 + float(v), 0.0f)); });
  r.positions = r.mesh.rest_positions;
  r.region = {2 * (5 * 12 + 5), 2 * (5 * 12 + 5) + 1};
  EXPECT_EQ(s.triangles.size(), 288u);
  return r;
}

TEST(Render, TheRefinedChildIsDrawnInPlaceOfTheTrianglesItStandsFor) {
  const Scene s = flat();
  Renderer r(240, 240, 1);
  Style st = bare_style();
  st.color = ColorMode::Weft;
  st.strain_range = 0.05;
  st.background = {0, 0, 0};
  st.refined_edges = false;
  const ClothFrame rest = rest_frame(s);
  const Viewport vp = r.scene_viewport(st);
  const Camera cam = frame_points(rest.positions, 35.0, static_cast<double>(vp.width) / vp.height);
  const Projection P = r.projection(cam, st, rest.positions);
  // Inside one child triangle, off its edges: a quarter cell right of the quad's centre, and a
  // tenth below.
  const float h = 0.3f / 12;
  const Vec3f probe(5.75f * h, 5.4f * h, 0.0f);
  const auto pixel = [&](const ClothFrame& f) {
    const Eigen::Vector2d q = P.to_pixel(probe.cast<double>());
    return r.render(s, f, nullptr, cam, st).at(static_cast<int>(q.x()), static_cast<int>(q.y()));
  };
  const Rgb grey = pixel(rest);
  EXPECT_LT(std::abs(grey[0] - grey[2]), 15);
  // The child stretched 5% along the weft about the quad's centre: red where it is.
  ClothFrame stretched = rest;
  const Vec3f centre(5.5f * h, 5.5f * h, 0.0f);
  stretched.refined = child_of_quad(s, [&](Vec3f p) { return Vec3f(centre.x() + 1.05f * (p.x() - centre.x()), p.y(), 0.0f); });
  const Rgb red = pixel(stretched);
  EXPECT_GT(red[0] - red[2], 60) << int(red[0]) << " " << int(red[2]);
  // Moved 10 m away, the child leaves a hole: the global triangles it stands for are not drawn.
  ClothFrame away = rest;
  away.refined = child_of_quad(s, [](Vec3f p) { return Vec3f(p.x() + 10.0f, p.y(), p.z()); });
  const Rgb hole = pixel(away);
  EXPECT_EQ(hole, st.background);
  // A region naming a triangle the mesh lacks is refused, not drawn.
  away.refined.region.push_back(288);
  EXPECT_THROW(r.render(s, away, nullptr, cam, st), std::invalid_argument);
}

TEST(Render, TheRefinedChildsEdgesAreDrawn) {
  const Scene s = flat();
  Renderer r(240, 240, 2);
  Style st = bare_style();
  st.color = ColorMode::Weft;  // at rest a uniform light grey
  st.background = {0, 0, 0};
  ClothFrame f = rest_frame(s);
  f.refined = child_of_quad(s, [](Vec3f p) { return p; });
  const Viewport vp = r.scene_viewport(st);
  const Camera cam = frame_points(f.positions, 35.0, static_cast<double>(vp.width) / vp.height);
  const Projection P = r.projection(cam, st, f.positions);
  // Along the child's middle edge (u at the quad's centre), the edge line is darker than the
  // same pixels drawn without it.
  const float h = 0.3f / 12;
  const auto column_sum = [&](const Image& img) {
    long sum = 0;
    for (int k = 1; k < 10; ++k) {
      const Eigen::Vector2d q = P.to_pixel(Vec3f(5.5f * h, (5.0f + 0.1f * k) * h, 0.0f).cast<double>());
      const Rgb c = img.at(static_cast<int>(std::lround(q.x())), static_cast<int>(q.y()));
      sum += c[0] + c[1] + c[2];
    }
    return sum;
  };
  const long with = column_sum(r.render(s, f, nullptr, cam, st));
  st.refined_edges = false;
  const long without = column_sum(r.render(s, f, nullptr, cam, st));
  EXPECT_LT(with, 0.8 * without) << with << " " << without;
}

}  // namespace
