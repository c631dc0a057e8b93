// A pinhole camera: look-at, vertical field of view, and the projection the renderer uses, so
// callers (and tests) can map a scene point to its pixel.
#pragma once

#include <vector>

#include <Eigen/Core>

namespace hapticloth::render {

struct Camera {
  Eigen::Vector3d eye{0.0, -1.5, 0.5};
  Eigen::Vector3d target{0.0, 0.0, 0.0};
  Eigen::Vector3d up{0.0, 0.0, 1.0};  ///< scene frame: +z up
  double fov_deg = 35.0;              ///< vertical field of view
};

/// A pixel rectangle of the output image (x right, y down from the top row).
struct Viewport {
  int x = 0, y = 0, width = 1, height = 1;
};

/// Column-major 4x4 matrices as OpenGL takes them.
struct Projection {
  Eigen::Matrix4d view = Eigen::Matrix4d::Identity();
  Eigen::Matrix4d proj = Eigen::Matrix4d::Identity();
  Viewport viewport;
  /// Pixel coordinates of a scene point (continuous: pixel (i, j) covers [i, i+1) x [j, j+1)).
  Eigen::Vector2d to_pixel(const Eigen::Vector3d& p) const;
};

/// The projection of `cam` into `vp`; near and far planes enclose `points` (the scene).
Projection make_projection(const Camera& cam, const Viewport& vp,
                           const std::vector<Eigen::Vector3f>& points);

/// A camera that frames `points` (not empty) in a viewport of aspect ratio `aspect`
/// (width / height), looking at their bounding box centre. The direction: from the side where
/// the box is thinnest (-x or -y, 20 degrees above and 30 degrees to the side) when the box
/// stands up, else from above at 50 degrees (a cloth lying flat). The distance is the least
/// that keeps every point inside the frame, plus `margin` (a fraction of it).
Camera frame_points(const std::vector<Eigen::Vector3f>& points, double fov_deg, double aspect,
                    double margin = 0.06);

}  // namespace hapticloth::render
