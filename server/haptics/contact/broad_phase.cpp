#include "haptics/contact/broad_phase.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>

#include <fcl/geometry/bvh/BVH_model.h>
#include <fcl/math/bv/AABB.h>
#include <fcl/math/bv/utility.h>

namespace hapticloth::haptics {

using BV = fcl::AABBd;

struct BroadPhase::Impl {
  std::shared_ptr<fcl::BVHModel<BV>> model;
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
  refit(x);  // FCL allocates its second vertex buffer on the first refit: here, not on a step
}

BroadPhase::~BroadPhase() = default;

void BroadPhase::refit(const std::vector<Eigen::Vector3d>& x) {
  auto& m = *impl_->model;
  m.beginUpdateModel();
  for (size_t i = 0; i < x.size(); ++i) m.updateVertex(x[i]);
  m.endUpdateModel(true, true);  // bottom-up refit (correct for k-DOP)
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

// A depth-first walk of the hierarchy with the sphere against each node's box: no narrow phase
// (the caller tests its own samples), no allocation. fcl::collide, used before, tested each leaf
// triangle against the sphere with GJK and allocated on every query (the sphere shape, the
// contact list, traversal state; docs/contact.md, 'The model').
int BroadPhase::query_sphere(const Eigen::Vector3d& centre, double radius, int* out, int max_out) {
  const fcl::BVHModel<BV>& m = *impl_->model;
  const double r = radius + disp_, r2 = r * r;
  std::array<int, kMaxDepth> stack;
  int top = 0, n = 0;
  stack[top++] = 0;
  while (top > 0) {
    const fcl::BVNode<BV>& node = m.getBV(stack[--top]);
    double d2 = 0.0;  // from the centre to the node's box
    for (int k = 0; k < 3; ++k) {
      const double below = node.bv.min_[k] - centre[k], above = centre[k] - node.bv.max_[k];
      const double gap = std::max(0.0, std::max(below, above));
      d2 += gap * gap;
    }
    if (d2 > r2) continue;
    if (node.isLeaf()) {
      if (n < max_out) out[n++] = node.primitiveId();
      continue;
    }
    if (top + 2 > kMaxDepth) throw std::logic_error("broad phase: hierarchy deeper than its walk's stack");
    stack[top++] = node.rightChild();
    stack[top++] = node.leftChild();
  }
  std::sort(out, out + n);
  return static_cast<int>(std::unique(out, out + n) - out);
}

}  // namespace hapticloth::haptics
