// Offscreen rendering of a cloth state with OSMesa (no display needed): lit, two-sided cloth
// with per-vertex normals, coloured by a procedural weave texture or by one strain of eq. 4
// per triangle (with a colour bar); fingertips as spheres with their force arrows. Where the
// simulation refines the cloth under a fingertip (paper 4.2.2), the refined child is drawn in
// place of the global triangles it stands in for, with its edges.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "render/camera.hpp"
#include "render/image.hpp"
#include "render/recording.hpp"

namespace hapticloth::render {

enum class ColorMode { Weave, Weft, Warp, Shear };

/// "weave", "weft", "warp", "shear"; false for anything else.
bool parse_color_mode(const std::string& s, ColorMode& out);
const char* color_mode_name(ColorMode m);

struct Style {
  ColorMode color = ColorMode::Weave;
  double strain_range = 0.01;     ///< strain at either end of the colour bar (> 0); 0.01 = 1%
  double weave_pitch = 0.02;      ///< m of cloth per repeat of the weave texture (4 threads)
  bool fingers = true;            ///< draw the fingertips (needs haptic samples)
  double finger_radius = 0.008;   ///< m
  double force_scale = 0.02;      ///< m of arrow per N of force; 0: no arrows
  bool colorbar = true;           ///< strain modes: the colour bar at the right
  bool refined_edges = true;      ///< the edges of the refined children under the fingertips
  bool label = true;              ///< time, scene and finger forces (swatch filled: in contact) at the top left
  Rgb background{246, 246, 243};
};

/// The colour of a strain relative to the bar's range: x in [-1, 1] (clamped) from blue
/// (compression) through light grey (0) to red (stretch).
Rgb diverging_color(double x);

class Renderer {
 public:
  /// An OSMesa context for width x height pictures, drawn at supersample times the size and
  /// averaged down (anti-aliasing). Throws std::runtime_error if OSMesa cannot create it.
  Renderer(int width, int height, int supersample = 2);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  int width() const { return width_; }
  int height() const { return height_; }

  /// The part of the picture the 3D view fills: all of it, less the colour bar's strip at the
  /// right when `style` shows one.
  Viewport scene_viewport(const Style& style) const;

  /// The projection render() uses for `cam` (and a scene made of `points`).
  Projection projection(const Camera& cam, const Style& style, const std::vector<Vec3f>& points) const;

  /// Draws the cloth at `frame` (positions of `scene`'s vertices) and, if `haptics` is not
  /// null, its fingertips. Not thread-safe (one context).
  Image render(const Scene& scene, const ClothFrame& frame, const HapticTick* haptics,
               const Camera& cam, const Style& style);

 private:
  struct Impl;
  void begin_frame(const Projection& P, const Style& style);
  void draw_cloth(const Scene& scene, const ClothFrame& frame, const Style& style);
  void draw_fingertips(const HapticTick& haptics, const Style& style);
  Image read_back() const;

  int width_, height_, ss_;
  std::unique_ptr<Impl> impl_;
};

/// What a picture must show: the cloth positions and, when fingers are drawn, the fingertip
/// spheres (centre +- radius along each axis).
std::vector<Vec3f> framing_points(const ClothFrame& frame, const HapticTick* haptics, const Style& style);

}  // namespace hapticloth::render
