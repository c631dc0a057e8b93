#include "render/image.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>

#include <zlib.h>

namespace hapticloth::render {

Image::Image(int w, int h, Rgb fill) : width(w), height(h), rgb(3 * static_cast<std::size_t>(w) * h) {
  for (std::size_t i = 0; i < rgb.size(); i += 3) {
    rgb[i] = fill[0];
    rgb[i + 1] = fill[1];
    rgb[i + 2] = fill[2];
  }
}

Image downsample(const Image& src, int factor) {
  if (factor <= 1) return src;
  Image out(src.width / factor, src.height / factor);
  const int n = factor * factor;
  for (int y = 0; y < out.height; ++y)
    for (int x = 0; x < out.width; ++x) {
      int sum[3] = {0, 0, 0};
      for (int j = 0; j < factor; ++j) {
        const std::uint8_t* p = &src.rgb[3 * (static_cast<std::size_t>(y * factor + j) * src.width + x * factor)];
        for (int i = 0; i < factor; ++i)
          for (int c = 0; c < 3; ++c) sum[c] += p[3 * i + c];
      }
      out.set(x, y, {static_cast<std::uint8_t>((sum[0] + n / 2) / n),
                     static_cast<std::uint8_t>((sum[1] + n / 2) / n),
                     static_cast<std::uint8_t>((sum[2] + n / 2) / n)});
    }
  return out;
}

void fill_rect(Image& img, int x0, int y0, int x1, int y1, Rgb c, double alpha) {
  for (int y = std::max(0, y0); y < std::min(img.height, y1); ++y)
    for (int x = std::max(0, x0); x < std::min(img.width, x1); ++x) {
      if (alpha >= 1.0) {
        img.set(x, y, c);
        continue;
      }
      const Rgb o = img.at(x, y);
      Rgb m;
      for (int k = 0; k < 3; ++k) m[k] = static_cast<std::uint8_t>(std::lround(o[k] + alpha * (c[k] - o[k])));
      img.set(x, y, m);
    }
}

// --- 5x7 bitmap font ---------------------------------------------------------------------------

namespace {

struct Glyph {
  char c;
  const char* rows;  // 7 rows of 5 columns ('1' = ink, separated by spaces), an 8th for descenders
};

// clang-format off
constexpr Glyph kFont[] = {
  {' ', "00000 00000 00000 00000 00000 00000 00000"},
  {'!', "00100 00100 00100 00100 00100 00000 00100"},
  {'%', "11000 11001 00010 00100 01000 10011 00011"},
  {'(', "00010 00100 01000 01000 01000 00100 00010"},
  {')', "01000 00100 00010 00010 00010 00100 01000"},
  {'+', "00000 00100 00100 11111 00100 00100 00000"},
  {',', "00000 00000 00000 00000 01100 00100 01000"},
  {'-', "00000 00000 00000 11111 00000 00000 00000"},
  {'.', "00000 00000 00000 00000 00000 01100 01100"},
  {'/', "00001 00010 00010 00100 01000 01000 10000"},
  {'0', "01110 10001 10011 10101 11001 10001 01110"},
  {'1', "00100 01100 00100 00100 00100 00100 01110"},
  {'2', "01110 10001 00001 00010 00100 01000 11111"},
  {'3', "11111 00010 00100 00010 00001 10001 01110"},
  {'4', "00010 00110 01010 10010 11111 00010 00010"},
  {'5', "11111 10000 11110 00001 00001 10001 01110"},
  {'6', "00110 01000 10000 11110 10001 10001 01110"},
  {'7', "11111 00001 00010 00100 01000 01000 01000"},
  {'8', "01110 10001 10001 01110 10001 10001 01110"},
  {'9', "01110 10001 10001 01111 00001 00010 01100"},
  {':', "00000 01100 01100 00000 01100 01100 00000"},
  {'=', "00000 00000 11111 00000 11111 00000 00000"},
  {'?', "01110 10001 00001 00010 00100 00000 00100"},
  {'A', "01110 10001 10001 11111 10001 10001 10001"},
  {'B', "11110 10001 10001 11110 10001 10001 11110"},
  {'C', "01110 10001 10000 10000 10000 10001 01110"},
  {'D', "11100 10010 10001 10001 10001 10010 11100"},
  {'E', "11111 10000 10000 11110 10000 10000 11111"},
  {'F', "11111 10000 10000 11110 10000 10000 10000"},
  {'G', "01110 10001 10000 10111 10001 10001 01111"},
  {'H', "10001 10001 10001 11111 10001 10001 10001"},
  {'I', "01110 00100 00100 00100 00100 00100 01110"},
  {'J', "00111 00010 00010 00010 00010 10010 01100"},
  {'K', "10001 10010 10100 11000 10100 10010 10001"},
  {'L', "10000 10000 10000 10000 10000 10000 11111"},
  {'M', "10001 11011 10101 10101 10001 10001 10001"},
  {'N', "10001 10001 11001 10101 10011 10001 10001"},
  {'O', "01110 10001 10001 10001 10001 10001 01110"},
  {'P', "11110 10001 10001 11110 10000 10000 10000"},
  {'Q', "01110 10001 10001 10001 10101 10010 01101"},
  {'R', "11110 10001 10001 11110 10100 10010 10001"},
  {'S', "01111 10000 10000 01110 00001 00001 11110"},
  {'T', "11111 00100 00100 00100 00100 00100 00100"},
  {'U', "10001 10001 10001 10001 10001 10001 01110"},
  {'V', "10001 10001 10001 10001 10001 01010 00100"},
  {'W', "10001 10001 10001 10101 10101 10101 01010"},
  {'X', "10001 10001 01010 00100 01010 10001 10001"},
  {'Y', "10001 10001 01010 00100 00100 00100 00100"},
  {'Z', "11111 00001 00010 00100 01000 10000 11111"},
  {'_', "00000 00000 00000 00000 00000 00000 00000 11111"},
  {'a', "00000 00000 01110 00001 01111 10001 01111"},
  {'b', "10000 10000 10110 11001 10001 10001 11110"},
  {'c', "00000 00000 01110 10000 10000 10001 01110"},
  {'d', "00001 00001 01101 10011 10001 10001 01111"},
  {'e', "00000 00000 01110 10001 11111 10000 01110"},
  {'f', "00110 01001 01000 11100 01000 01000 01000"},
  {'g', "00000 00000 01111 10001 10001 01111 00001 01110"},
  {'h', "10000 10000 10110 11001 10001 10001 10001"},
  {'i', "00100 00000 01100 00100 00100 00100 01110"},
  {'j', "00010 00000 00110 00010 00010 00010 10010 01100"},
  {'k', "10000 10000 10010 10100 11000 10100 10010"},
  {'l', "01100 00100 00100 00100 00100 00100 01110"},
  {'m', "00000 00000 11010 10101 10101 10001 10001"},
  {'n', "00000 00000 10110 11001 10001 10001 10001"},
  {'o', "00000 00000 01110 10001 10001 10001 01110"},
  {'p', "00000 00000 11110 10001 10001 11110 10000 10000"},
  {'q', "00000 00000 01111 10001 10001 01111 00001 00001"},
  {'r', "00000 00000 10110 11001 10000 10000 10000"},
  {'s', "00000 00000 01110 10000 01110 00001 11110"},
  {'t', "01000 01000 11100 01000 01000 01001 00110"},
  {'u', "00000 00000 10001 10001 10001 10011 01101"},
  {'v', "00000 00000 10001 10001 10001 01010 00100"},
  {'w', "00000 00000 10001 10001 10101 10101 01010"},
  {'x', "00000 00000 10001 01010 00100 01010 10001"},
  {'y', "00000 00000 10001 10001 10001 01111 00001 01110"},
  {'z', "00000 00000 11111 00010 00100 01000 11111"},
  {'|', "00100 00100 00100 00100 00100 00100 00100"},
};
// clang-format on

const Glyph& glyph(char c) {
  for (const Glyph& g : kFont)
    if (g.c == c) return g;
  for (const Glyph& g : kFont)
    if (g.c == '?') return g;
  return kFont[0];
}

}  // namespace

int text_width(const std::string& text, int scale) {
  return text.empty() ? 0 : static_cast<int>(text.size()) * 6 * scale - scale;
}

void draw_text(Image& img, int x, int y, const std::string& text, int scale, Rgb c) {
  for (char ch : text) {
    const char* r = glyph(ch).rows;
    const int rows = static_cast<int>((std::strlen(r) + 1) / 6);
    for (int row = 0; row < rows; ++row)
      for (int col = 0; col < 5; ++col)
        if (r[row * 6 + col] == '1') fill_rect(img, x + col * scale, y + row * scale,
                                               x + (col + 1) * scale, y + (row + 1) * scale, c);
    x += 6 * scale;
  }
}

// --- PNG -----------------------------------------------------------------------------------------

namespace {

void put_u32(std::vector<std::uint8_t>& out, std::uint32_t v) {
  for (int s = 24; s >= 0; s -= 8) out.push_back(static_cast<std::uint8_t>(v >> s));
}

void put_chunk(std::vector<std::uint8_t>& out, const char type[4], const std::vector<std::uint8_t>& data) {
  put_u32(out, static_cast<std::uint32_t>(data.size()));
  const std::size_t start = out.size();
  out.insert(out.end(), type, type + 4);
  out.insert(out.end(), data.begin(), data.end());
  const uLong crc = crc32(0L, out.data() + start, static_cast<uInt>(out.size() - start));
  put_u32(out, static_cast<std::uint32_t>(crc));
}

int paeth(int a, int b, int c) {
  const int p = a + b - c, pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
  return pa <= pb && pa <= pc ? a : (pb <= pc ? b : c);
}

// One filtered scanline: the filter type (PNG spec, 9.2) whose output has the smallest sum of
// absolute values, the usual heuristic.
void filter_row(const std::uint8_t* row, const std::uint8_t* prev, int bytes, std::vector<std::uint8_t>& out) {
  std::vector<std::uint8_t> best, cand(bytes);
  long best_sum = -1;
  for (int type = 0; type < 5; ++type) {
    long sum = 0;
    for (int i = 0; i < bytes; ++i) {
      const int a = i >= 3 ? row[i - 3] : 0, b = prev ? prev[i] : 0, c = (prev && i >= 3) ? prev[i - 3] : 0;
      const int pred = type == 0 ? 0 : type == 1 ? a : type == 2 ? b : type == 3 ? (a + b) / 2 : paeth(a, b, c);
      cand[i] = static_cast<std::uint8_t>(row[i] - pred);
      sum += cand[i] < 128 ? cand[i] : 256 - cand[i];
    }
    if (best_sum < 0 || sum < best_sum) {
      best_sum = sum;
      best = cand;
      best.insert(best.begin(), static_cast<std::uint8_t>(type));
    }
  }
  out.insert(out.end(), best.begin(), best.end());
}

}  // namespace

void write_png(const std::string& path, const Image& img) {
  const int bytes = 3 * img.width;
  std::vector<std::uint8_t> raw;
  raw.reserve(static_cast<std::size_t>(bytes + 1) * img.height);
  for (int y = 0; y < img.height; ++y)
    filter_row(&img.rgb[static_cast<std::size_t>(y) * bytes],
               y > 0 ? &img.rgb[static_cast<std::size_t>(y - 1) * bytes] : nullptr, bytes, raw);
  uLongf zlen = compressBound(static_cast<uLong>(raw.size()));
  std::vector<std::uint8_t> z(zlen);
  if (compress2(z.data(), &zlen, raw.data(), static_cast<uLong>(raw.size()), 6) != Z_OK)
    throw std::runtime_error(path + ": PNG compression failed");
  z.resize(zlen);

  std::vector<std::uint8_t> out = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  std::vector<std::uint8_t> ihdr;
  put_u32(ihdr, static_cast<std::uint32_t>(img.width));
  put_u32(ihdr, static_cast<std::uint32_t>(img.height));
  ihdr.insert(ihdr.end(), {8, 2, 0, 0, 0});  // 8 bits, RGB, deflate, adaptive filters, no interlace
  put_chunk(out, "IHDR", ihdr);
  put_chunk(out, "IDAT", z);
  put_chunk(out, "IEND", {});

  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) throw std::runtime_error(path + ": cannot write (" + std::strerror(errno) + ")");
  const bool ok = std::fwrite(out.data(), 1, out.size(), f) == out.size();
  if (std::fclose(f) != 0 || !ok) throw std::runtime_error(path + ": write failed");
}

}  // namespace hapticloth::render
