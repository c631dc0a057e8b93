// The Integrator's point springs and proxies: the contact springs' and the fingertip proxies'
// terms in the system, taken out of a kept matrix and added again, and the response model.
#include "cloth/integrator.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <numeric>
#include <stdexcept>
#include <string>

namespace hapticloth::cloth {

namespace {

// Adds the 3x3 block B at `offset` of a CSR value array whose rows are `stride` apart.
inline void add_block(double* val, int offset, int stride, const Mat3& B) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) val[offset + r * stride + c] += B(r, c);
}

}  // namespace

// f(row) for each block row the terms of `springs` reach (add_springs): their proxies' and
// their free corners', repeats included.
template <class F>
void Integrator::for_each_spring_row(const std::vector<PointSpring>& springs, F&& f) const {
  for (const PointSpring& sp : springs) {
    f(sys_.free_nodes + sp.proxy);
    for (int v : model_.elements[sp.tri].v)
      if (model_.free_index[v] >= 0) f(model_.free_index[v]);
  }
}

// A kept matrix holds the last assembly's proxies and point springs (springs_in_matrix_): their
// blocks in the proxies' rows and columns are set to zero (only they write there, so no rounding
// is left behind for the PCG's hub blocks to keep), and their corner blocks are taken back out
// of the cloth's. The rows they reach are marked changed.
void Integrator::take_out_springs(double h) {
  const double ah = alpha_ * h, aahh = ah * ah;
  const int nf = sys_.free_nodes, rest = static_cast<int>(part_free_.size()) - 1;
  double* const val = A_.val.data();
  const auto set_zero = [&](int offset, int stride) {
    for (int r = 0; r < 3; ++r) std::fill_n(val + offset + r * stride, 3, 0.0);
  };
  for (int j = 0; j < cfg_.proxies; ++j) set_zero(sys_.diag_offset[nf + j], sys_.row_stride[nf + j]);
  for (const PointSpring& sp : springs_in_matrix_) {
    const auto& e = model_.elements[sp.tri];
    const int node = nf + sp.proxy;
    const Mat3 Kh = -aahh * sp.K;
    const auto& off = sys_.block_offset[sp.tri];
    for (int k = 0; k < 3; ++k) {
      const int fk = model_.free_index[e.v[k]];
      if (fk < 0) continue;
      kept_->mark(rest, fk);
      set_zero(A_.rowptr[3 * fk] + sys_.row_stride[fk] - 3 * (cfg_.proxies - sp.proxy), sys_.row_stride[fk]);
      set_zero(A_.rowptr[3 * node] + 3 * fk, sys_.row_stride[node]);
      for (int l = 0; l < 3; ++l)
        if (off[k * 3 + l] >= 0) add_block(val, off[k * 3 + l], sys_.row_stride[fk], sp.b[k] * sp.b[l] * Kh);
    }
  }
}

// The rows a kept matrix's proxies and springs changed (assemble_proxies): every proxy's (its
// coupling is written anew) and the springs' free corners.
void Integrator::mark_proxy_rows() {
  const int nf = sys_.free_nodes, rest = static_cast<int>(part_free_.size()) - 1;
  for (int j = 0; j < cfg_.proxies; ++j) kept_->mark(rest, nf + j);
  for_each_spring_row(springs_, [&](int row) { kept_->mark(rest, row); });
}

// The proxies and point springs in eq. 9. A proxy is a node without mass or velocity of its own
// (quasi-static), so its unknown dv_p gives the displacement alpha h dv_p like a vertex at rest.
// Its coupling to the target (stiffness k, damping c) adds alpha^2 h^2 k + alpha h c to its
// diagonal and h (k (target - x) + c target_velocity) to its right-hand side. A point spring
// at x_q = sum b_k x_k with force f and stiffness K acts on the relative displacement of the
// point and the proxy: blocks alpha^2 h^2 b_k b_l K between corners, -alpha^2 h^2 b_k K between a
// corner and the proxy, alpha^2 h^2 K on the proxy; right-hand sides h b_k (f - alpha h K v_q)
// on the corners and minus their sum on the proxy.
void Integrator::assemble_proxies(const ClothState& s, double h) {
  const double ah = alpha_ * h, aahh = ah * ah;
  const int nf = sys_.free_nodes;
  double* const val = A_.val.data();
  for (int j = 0; j < cfg_.proxies; ++j) {
    const ProxyNode& p = proxies_[j];
    const int node = nf + j;
    const Mat3 K = p.stiffness_matrix();  // k I, or anisotropic along p.axis
    add_block(val, sys_.diag_offset[node], sys_.row_stride[node], aahh * K + ah * p.damping * Mat3::Identity());
    rhs_.segment<3>(3 * node) += h * (K * (p.target - p.x) + p.damping * p.target_velocity);
  }
  add_springs(s, h, springs_, 1.0);
}

// The point springs' terms of eq. 9, times `sign` (-1 takes a set back out before a re-solve).
void Integrator::add_springs(const ClothState& s, double h, const std::vector<PointSpring>& springs,
                             double sign) {
  const double ah = alpha_ * h, aahh = ah * ah;
  const int nf = sys_.free_nodes;
  double* const val = A_.val.data();
  for (const PointSpring& sp : springs) {
    const auto& e = model_.elements[sp.tri];
    const int node = nf + sp.proxy;
    Vec3 vq = Vec3::Zero();
    for (int k = 0; k < 3; ++k) vq += sp.b[k] * s.v[e.v[k]];
    const Vec3 g = sign * h * (sp.f - ah * (sp.K * vq));
    rhs_.segment<3>(3 * node) -= g;
    const Mat3 Kh = sign * aahh * sp.K;
    add_block(val, sys_.diag_offset[node], sys_.row_stride[node], Kh);
    const auto& off = sys_.block_offset[sp.tri];
    for (int k = 0; k < 3; ++k) {
      const int fk = model_.free_index[e.v[k]];
      if (fk < 0) continue;
      rhs_.segment<3>(3 * fk) += sp.b[k] * g;
      // corner row: the proxy's columns come last in it; the proxy's row lists every free node
      const int corner_proxy = A_.rowptr[3 * fk] + sys_.row_stride[fk] - 3 * (cfg_.proxies - sp.proxy);
      add_block(val, corner_proxy, sys_.row_stride[fk], -sp.b[k] * Kh);
      add_block(val, A_.rowptr[3 * node] + 3 * fk, sys_.row_stride[node], -sp.b[k] * Kh);
      for (int l = 0; l < 3; ++l)
        if (off[k * 3 + l] >= 0) add_block(val, off[k * 3 + l], sys_.row_stride[fk], sp.b[k] * sp.b[l] * Kh);
    }
  }
}

// The block rows that the springs' terms reach (add_springs): their proxies' and their free
// corners', each added once to spring_rows_.
void Integrator::mark_spring_rows(const std::vector<PointSpring>& springs) {
  for_each_spring_row(springs, [&](int row) {
    if (spring_row_marked_[row]) return;
    spring_row_marked_[row] = 1;
    spring_rows_.push_back(row);
  });
}

// Work done on the cloth by the point springs over the candidate step (their start-of-step
// forces on the displacement of their points): the user's energy input through the fingertips.
double Integrator::contact_work(const ClothState& s) const {
  double w = 0.0;
  for (const PointSpring& sp : springs_) {
    const auto& e = model_.elements[sp.tri];
    Vec3 dq = Vec3::Zero();
    for (int k = 0; k < 3; ++k) dq += sp.b[k] * (xn_[e.v[k]] - s.x[e.v[k]]);
    w += sp.f.dot(dq);
  }
  return w;
}

bool Integrator::proxy_response(std::vector<Mat3>& R) {
  const int P = cfg_.proxies, nf = sys_.free_nodes;
  R.assign(static_cast<size_t>(P) * P, Mat3::Zero());
  if (P == 0 || !(last_h_ > 0.0)) return false;
  if (response_.size() != static_cast<size_t>(3 * P)) {
    response_.assign(3 * P, Eigen::VectorXd::Zero(A_.n));
    unit_.setZero(A_.n);
  }
  const double h = last_h_, ah = alpha_ * h;
  const WorkerPool::Burst burst(pool_.get());  // 3 P solves in a row (as in single_step)
  // Unit right-hand sides: solved relative to |b| alone (single_step sets the weight's scale
  // again for the next step).
  solver_->set_residual_scale(0.0);
  for (int q = 0; q < P; ++q)
    for (int c = 0; c < 3; ++c) {
      // d b_q / d T_q = h k_q (the coupling's right-hand side), so d dv / d T_q = A^-1 h k_q e;
      // x_p = x0 + alpha h dv_p and v_p = dv_p then give R (see the header).
      const double scale = h * (ah * proxies_[q].stiffness + proxies_[q].damping);
      const int row = 3 * (nf + q) + c;
      Eigen::VectorXd& x = response_[3 * q + c];
      unit_[row] = 1.0;
      const SolveStatus st = solver_->resolve(A_, unit_.data(), x.data());
      unit_[row] = 0.0;
      if (st != SolveStatus::Ok || !x.allFinite()) {
        x.setZero();
        return false;
      }
      for (int p = 0; p < P; ++p) R[p * P + q].col(c) = scale * x.segment<3>(3 * (nf + p));
    }
  return true;
}

// Depth along its normal of a one-sided spring's point at the end of the step dv (alpha 1: the
// point moves h (v + dv), the proxy h dv_p), m.
double Integrator::spring_depth(const PointSpring& sp, const ClothState& s, double h,
                                const Eigen::VectorXd& dv) const {
  const auto& e = model_.elements[sp.tri];
  Vec3 r = -h * dv.segment<3>(3 * (sys_.free_nodes + sp.proxy));
  for (int k = 0; k < 3; ++k) {
    const int fk = model_.free_index[e.v[k]];
    r += sp.b[k] * h * (fk < 0 ? s.v[e.v[k]] : Vec3(s.v[e.v[k]] + dv.segment<3>(3 * fk)));
  }
  return sp.depth0 - sp.n.dot(r);
}

}  // namespace hapticloth::cloth
