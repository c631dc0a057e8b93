// The PNG encoder (clients/render/image): a rendered image round-trips through write_png and a
// decoder written here.
#include <gtest/gtest.h>

#include "render_fixtures.hpp"

namespace {

using namespace hapticloth::render;
using namespace hapticloth::render::test;

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


}  // namespace
