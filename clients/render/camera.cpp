#include "render/camera.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

namespace hapticloth::render {

namespace {

constexpr double kPi = 3.14159265358979323846;

struct Basis {
  Eigen::Vector3d right, up, back;  // back points from the target to the eye
};

Basis basis(const Eigen::Vector3d& eye, const Eigen::Vector3d& target, const Eigen::Vector3d& up) {
  Basis b;
  b.back = (eye - target).normalized();
  Eigen::Vector3d u = up - up.dot(b.back) * b.back;
  if (u.norm() < 1e-9) u = std::abs(b.back.z()) < 0.9 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitY();
  b.right = u.cross(b.back).normalized();
  b.up = b.back.cross(b.right);
  return b;
}

}  // namespace

Eigen::Vector2d Projection::to_pixel(const Eigen::Vector3d& p) const {
  const Eigen::Vector4d c = proj * view * p.homogeneous();
  const double x = c.x() / c.w(), y = c.y() / c.w();
  return {viewport.x + (x + 1.0) * 0.5 * viewport.width, viewport.y + (1.0 - y) * 0.5 * viewport.height};
}

Projection make_projection(const Camera& cam, const Viewport& vp, const std::vector<Eigen::Vector3f>& points) {
  Projection P;
  P.viewport = vp;
  const Basis b = basis(cam.eye, cam.target, cam.up);
  Eigen::Matrix3d R;
  R.row(0) = b.right;
  R.row(1) = b.up;
  R.row(2) = b.back;
  P.view.setIdentity();
  P.view.topLeftCorner<3, 3>() = R;
  P.view.topRightCorner<3, 1>() = -R * cam.eye;

  // Near and far from the depth range of the scene (clamped so depth precision stays useful).
  double zmin = 1e30, zmax = 0.0;
  for (const auto& p : points) {
    const double d = -(P.view * p.cast<double>().homogeneous()).z();
    zmin = std::min(zmin, d);
    zmax = std::max(zmax, d);
  }
  if (points.empty() || zmax <= 0.0) {
    zmin = 0.01;
    zmax = 100.0;
  }
  const double f = zmax * 1.5 + 0.1, n = std::max({zmin * 0.5, f * 1e-4, 1e-3});
  const double aspect = static_cast<double>(vp.width) / vp.height;
  const double t = 1.0 / std::tan(cam.fov_deg * kPi / 360.0);
  P.proj.setZero();
  P.proj(0, 0) = t / aspect;
  P.proj(1, 1) = t;
  P.proj(2, 2) = -(f + n) / (f - n);
  P.proj(2, 3) = -2.0 * f * n / (f - n);
  P.proj(3, 2) = -1.0;
  return P;
}

Camera frame_points(const std::vector<Eigen::Vector3f>& points, double fov_deg, double aspect, double margin) {
  Eigen::AlignedBox3d box;
  for (const auto& p : points) box.extend(p.cast<double>());
  const Eigen::Vector3d size = box.sizes();
  const Eigen::Vector3d centre = box.center();

  // The viewing direction (from the target towards the eye).
  const double deg = kPi / 180.0;
  Eigen::Vector3d dir;
  if (size.z() < 0.5 * std::min(size.x(), size.y())) {
    dir = Eigen::Vector3d(std::sin(20 * deg) * std::cos(50 * deg), -std::cos(20 * deg) * std::cos(50 * deg),
                          std::sin(50 * deg));
  } else {
    const double side = std::cos(20 * deg) * std::sin(30 * deg), front = std::cos(20 * deg) * std::cos(30 * deg);
    dir = size.y() <= size.x() ? Eigen::Vector3d(side, -front, std::sin(20 * deg))
                               : Eigen::Vector3d(-front, -side, std::sin(20 * deg));
  }
  Camera cam;
  cam.fov_deg = fov_deg;
  cam.target = centre;
  cam.up = Eigen::Vector3d::UnitZ();
  const Basis b = basis(centre + dir, centre, cam.up);

  // A point p (relative to the target) lies at depth d - p.back in front of an eye at distance
  // d; it is inside the frame when |p.right| <= tan(fovx/2) depth and |p.up| <= tan(fovy/2) depth.
  const double ty = std::tan(fov_deg * kPi / 360.0), tx = ty * aspect;
  double d = 1e-3;
  for (const auto& p3 : points) {
    const Eigen::Vector3d p = p3.cast<double>() - centre;
    d = std::max({d, p.dot(b.back) + std::abs(p.dot(b.right)) / tx, p.dot(b.back) + std::abs(p.dot(b.up)) / ty});
  }
  cam.eye = centre + dir * d * (1.0 + margin);
  return cam;
}

}  // namespace hapticloth::render
