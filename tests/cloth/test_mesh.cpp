// Generated meshes: the graded disc (make_disc, disc_rim).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>
#include <utility>

#include <Eigen/Geometry>

#include "cloth/mesh.hpp"

using hapticloth::cloth::DiscSpec;
using hapticloth::cloth::disc_rim;
using hapticloth::cloth::make_disc;
using hapticloth::cloth::Mesh;

namespace {

double signed_area(const Mesh& m, int t) {
  const auto& tri = m.triangles[t];
  const Eigen::Vector3d& a = m.positions[tri[0]];
  const Eigen::Vector3d& b = m.positions[tri[1]];
  const Eigen::Vector3d& c = m.positions[tri[2]];
  return 0.5 * (b - a).cross(c - a).z();
}

/// Undirected edge -> number of triangles using it.
std::map<std::pair<int, int>, int> edge_use(const Mesh& m) {
  std::map<std::pair<int, int>, int> e;
  for (const auto& t : m.triangles)
    for (int q = 0; q < 3; ++q) {
      const int a = t[q], b = t[(q + 1) % 3];
      ++e[{std::min(a, b), std::max(a, b)}];
    }
  return e;
}

double min_angle_deg(const Mesh& m) {
  double out = 180.0;
  for (const auto& t : m.triangles)
    for (int q = 0; q < 3; ++q) {
      const Eigen::Vector3d u = m.positions[t[(q + 1) % 3]] - m.positions[t[q]];
      const Eigen::Vector3d v = m.positions[t[(q + 2) % 3]] - m.positions[t[q]];
      out = std::min(out, std::acos(u.dot(v) / (u.norm() * v.norm())) * 180.0 / M_PI);
    }
  return out;
}

DiscSpec spec_with_centre_edge(double ce) {
  DiscSpec s;
  s.centre_edge = ce;
  s.rim_edge = std::max(0.005, ce);
  s.centre = {0.3, -0.2, 0.05};
  return s;
}

const double kCentreEdges[] = {0.25e-3, 0.5e-3, 1e-3, 2e-3, 4e-3, 8e-3};

}  // namespace

TEST(Mesh, DiscAreaOrientationAndNoDegenerateTriangles) {
  for (double ce : kCentreEdges) {
    const DiscSpec s = spec_with_centre_edge(ce);
    const Mesh m = make_disc(s);
    ASSERT_EQ(m.weave_uv.size(), m.triangles.size());
    EXPECT_EQ(m.grid_nx, 0);
    EXPECT_EQ(m.grid_ny, 0);
    double area = 0.0;
    for (int t = 0; t < static_cast<int>(m.triangles.size()); ++t) {
      const double a = signed_area(m, t);
      // counter-clockwise from +z and far from degenerate (>= 5 % of an equilateral on ce)
      ASSERT_GT(a, 0.05 * std::sqrt(3.0) / 4.0 * ce * ce) << "ce " << ce << " triangle " << t;
      area += a;
    }
    // The area equals the inscribed rim polygon's, within a few 1e-4 of pi R^2.
    const std::vector<int> rim = disc_rim(m);
    double poly = 0.0;
    for (std::size_t i = 0; i < rim.size(); ++i) {
      const Eigen::Vector3d a = m.positions[rim[i]] - s.centre;
      const Eigen::Vector3d b = m.positions[rim[(i + 1) % rim.size()]] - s.centre;
      poly += 0.5 * (a.x() * b.y() - a.y() * b.x());
    }
    EXPECT_NEAR(area, poly, 1e-12) << "ce " << ce;
    EXPECT_NEAR(area / (M_PI * s.radius * s.radius), 1.0, 2e-3) << "ce " << ce;
    for (const auto& p : m.positions) EXPECT_DOUBLE_EQ(p.z(), s.centre.z());
  }
}

TEST(Mesh, DiscIsAManifoldWithTheRimAsOnlyBoundary) {
  for (double ce : kCentreEdges) {
    const DiscSpec s = spec_with_centre_edge(ce);
    const Mesh m = make_disc(s);
    const std::vector<int> rim = disc_rim(m);
    std::vector<char> on_rim(m.positions.size(), 0);
    for (int v : rim) on_rim[v] = 1;
    int boundary = 0;
    const auto edges = edge_use(m);
    for (const auto& [e, n] : edges) {
      ASSERT_TRUE(n == 1 || n == 2) << "edge used " << n << " times";
      const bool rim_edge = on_rim[e.first] && on_rim[e.second] && n == 1;
      if (n == 1) {
        ++boundary;
        EXPECT_TRUE(rim_edge);
      }
    }
    EXPECT_EQ(boundary, static_cast<int>(rim.size()));
    // Euler characteristic of a disc.
    EXPECT_EQ(static_cast<long>(m.positions.size()) - static_cast<long>(edges.size()) +
                  static_cast<long>(m.triangles.size()),
              1L);
    // Every rim vertex lies on the circle of the given radius; no other vertex does.
    for (std::size_t v = 0; v < m.positions.size(); ++v) {
      const double r = (m.positions[v] - s.centre).norm();
      if (on_rim[v]) EXPECT_NEAR(r, s.radius, 1e-12);
      else EXPECT_LT(r, s.radius - 0.25 * s.rim_edge);
    }
  }
}

TEST(Mesh, DiscEdgeLengthsAreGraded) {
  for (double ce : kCentreEdges) {
    const DiscSpec s = spec_with_centre_edge(ce);
    const Mesh m = make_disc(s);
    double lmax = 0.0;
    for (const auto& [e, n] : edge_use(m)) {
      (void)n;
      const Eigen::Vector3d a = m.positions[e.first] - s.centre;
      const Eigen::Vector3d b = m.positions[e.second] - s.centre;
      const double l = (a - b).norm();
      lmax = std::max(lmax, l);
      if (a.norm() < 3.0 * ce && b.norm() < 3.0 * ce) {
        EXPECT_GE(l, 0.5 * ce);
        EXPECT_LE(l, 2.0 * ce);
      }
    }
    EXPECT_LE(lmax, 2.0 * s.rim_edge);
  }
}

TEST(Mesh, DiscTrianglesAreWellShaped) {
  for (double ce : kCentreEdges) {
    const Mesh m = make_disc(spec_with_centre_edge(ce));
    EXPECT_GT(min_angle_deg(m), 25.0) << "ce " << ce;
  }
}

TEST(Mesh, DiscSizeForAFineCentre) {
  const Mesh m = make_disc(spec_with_centre_edge(0.25e-3));
  EXPECT_LE(m.triangles.size(), 10000u);
  EXPECT_GE(m.triangles.size(), 1000u);
}

TEST(Mesh, DiscWeaveCoordinatesAreTheRestPositions) {
  const DiscSpec s = spec_with_centre_edge(1e-3);
  const Mesh m = make_disc(s);
  for (std::size_t t = 0; t < m.triangles.size(); ++t)
    for (int q = 0; q < 3; ++q) {
      const Eigen::Vector3d& p = m.positions[m.triangles[t][q]];
      EXPECT_DOUBLE_EQ(m.weave_uv[t][q][0], p.x() - s.centre.x());
      EXPECT_DOUBLE_EQ(m.weave_uv[t][q][1], p.y() - s.centre.y());
    }
}

TEST(Mesh, DiscRimIsCounterClockwiseAndClosed) {
  const DiscSpec s = spec_with_centre_edge(2e-3);
  const Mesh m = make_disc(s);
  const std::vector<int> rim = disc_rim(m);
  ASSERT_GE(rim.size(), 6u);
  double turn = 0.0;
  for (std::size_t i = 0; i < rim.size(); ++i) {
    const Eigen::Vector3d a = m.positions[rim[i]] - s.centre;
    const Eigen::Vector3d b = m.positions[rim[(i + 1) % rim.size()]] - s.centre;
    turn += std::atan2(a.x() * b.y() - a.y() * b.x(), a.dot(b));
  }
  EXPECT_NEAR(turn, 2.0 * M_PI, 1e-9);
}

TEST(Mesh, DiscRejectsABadSpec) {
  const auto rejects = [](DiscSpec s, const std::string& field) {
    try {
      make_disc(s);
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
      return;
    }
    ADD_FAILURE() << "no exception for a bad " << field;
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  DiscSpec s;
  s.radius = -0.1; rejects(s, "radius");
  s = {}; s.radius = inf; rejects(s, "radius");
  s = {}; s.centre_edge = 0.0; rejects(s, "centre_edge");
  s = {}; s.centre_edge = nan; rejects(s, "centre_edge");
  s = {}; s.rim_edge = -1.0; rejects(s, "rim_edge");
  s = {}; s.centre_edge = 0.006; rejects(s, "centre_edge");  // > rim_edge
  s = {}; s.rim_edge = 0.1; rejects(s, "rim_edge");          // not < radius
  s = {}; s.growth = 0.9; rejects(s, "growth");
  s = {}; s.growth = nan; rejects(s, "growth");
  s = {}; s.centre.x() = nan; rejects(s, "centre");
}

TEST(Mesh, DiscRimRejectsAClosedMesh) {
  Mesh tet;
  tet.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  tet.triangles = {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {0, 3, 2}};
  EXPECT_THROW(disc_rim(tet), std::invalid_argument);
}
