#include "haptics/broad_phase.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <fcl/geometry/bvh/BVH_model.h>
#include <fcl/geometry/shape/sphere.h>
#include <fcl/math/bv/AABB.h>
#include <fcl/narrowphase/collision.h>
#include <fcl/narrowphase/collision_object.h>

namespace hapticloth::haptics {

using BV = fcl::AABBd;

struct BroadPhase::Impl {
  std::shared_ptr<fcl::BVHModel<BV>> model;
  std::shared_ptr<fcl::CollisionObjectd> cloth;
  std::vector<fcl::Vector3d> pts;
};

BroadPhase::BroadPhase(const std::vector<Eigen::Vector3d>& x,
                       const std::vector<std::array<int, 3>>& tris, double refit_slack)
    : impl_(std::make_unique<Impl>()), x_refit_(x), slack_(refit_slack),
      triangles_(static_cast<int>(tris.size())) {
  impl_->model = std::make_shared<fcl::BVHModel<BV>>();
  impl_->pts.assign(x.begin(), x.end());
  std::vector<fcl::Triangle> t;
  t.reserve(tris.size());
  for (const auto& a : tris) t.emplace_back(a[0], a[1], a[2]);
  impl_->model->beginModel(static_cast<int>(tris.size()), static_cast<int>(x.size()));
  impl_->model->addSubModel(impl_->pts, t);
  impl_->model->endModel();
  impl_->cloth = std::make_shared<fcl::CollisionObjectd>(impl_->model);
}

BroadPhase::~BroadPhase() = default;

void BroadPhase::refit(const std::vector<Eigen::Vector3d>& x) {
  auto& m = *impl_->model;
  m.beginUpdateModel();
  for (size_t i = 0; i < x.size(); ++i) m.updateVertex(x[i]);
  m.endUpdateModel(true, true);  // bottom-up refit (correct for k-DOP)
  impl_->cloth->computeAABB();
}

void BroadPhase::update(const std::vector<Eigen::Vector3d>& x) {
  double disp2 = 0.0;
  for (size_t i = 0; i < x.size(); ++i) disp2 = std::max(disp2, (x[i] - x_refit_[i]).squaredNorm());
  disp_ = std::sqrt(disp2);
  if (disp_ > slack_) {
    refit(x);
    std::copy(x.begin(), x.end(), x_refit_.begin());
    disp_ = 0.0;
    ++refits_;
  }
}

int BroadPhase::query_sphere(const Eigen::Vector3d& centre, double radius, int* out, int max_out) {
  fcl::CollisionObjectd sphere(std::make_shared<fcl::Sphered>(radius + disp_));
  sphere.setTranslation(centre);
  sphere.computeAABB();
  fcl::CollisionRequestd req(static_cast<std::size_t>(std::max(1, max_out)), false);
  fcl::CollisionResultd res;
  fcl::collide(&sphere, impl_->cloth.get(), req, res);
  int n = 0;
  for (size_t i = 0; i < res.numContacts() && n < max_out; ++i) {
    const auto& c = res.getContact(i);
    // FCL answers a shape-mesh query as mesh-shape: the triangle is b1 (b2 = NONE, -1).
    const int id = c.b1 >= 0 ? c.b1 : c.b2;
    if (id >= 0) out[n++] = id;
  }
  std::sort(out, out + n);
  return static_cast<int>(std::unique(out, out + n) - out);
}

}  // namespace hapticloth::haptics
