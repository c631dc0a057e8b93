// An 8-bit RGB image with what the renderer needs on the CPU side: box downsampling, filled
// rectangles, a small bitmap font and a PNG encoder (zlib).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace hapticloth::render {

using Rgb = std::array<std::uint8_t, 3>;

struct Image {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;  ///< row-major from the top row, 3 bytes per pixel

  Image() = default;
  Image(int w, int h, Rgb fill = {0, 0, 0});
  Rgb at(int x, int y) const {
    const std::uint8_t* p = &rgb[3 * (static_cast<std::size_t>(y) * width + x)];
    return {p[0], p[1], p[2]};
  }
  void set(int x, int y, Rgb c) {
    if (x < 0 || y < 0 || x >= width || y >= height) return;
    std::uint8_t* p = &rgb[3 * (static_cast<std::size_t>(y) * width + x)];
    p[0] = c[0];
    p[1] = c[1];
    p[2] = c[2];
  }
};

/// Averages factor x factor blocks (the supersampled render down to its output size).
Image downsample(const Image& src, int factor);

/// Fills [x0, x1) x [y0, y1), clipped to the image; alpha < 1 blends `c` over what is there.
void fill_rect(Image& img, int x0, int y0, int x1, int y1, Rgb c, double alpha = 1.0);

/// Pixel size of `text` in the 5x7 font at `scale` (each font pixel is scale x scale).
int text_width(const std::string& text, int scale);
inline int text_height(int scale) { return 7 * scale; }
/// Draws `text` with its top-left corner at (x, y); descenders (g, j, p, q, y, _) reach one font
/// pixel below text_height. Characters the font lacks show as '?'.
void draw_text(Image& img, int x, int y, const std::string& text, int scale, Rgb c);

/// Writes `img` as an 8-bit RGB PNG. Throws std::runtime_error naming the path on failure.
void write_png(const std::string& path, const Image& img);

}  // namespace hapticloth::render
