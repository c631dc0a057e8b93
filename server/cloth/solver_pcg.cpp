#include <Eigen/Dense>
#include <array>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "cloth/solver.hpp"

namespace hapticloth::cloth {

const char* to_string(SolveStatus s) {
  switch (s) {
    case SolveStatus::Ok: return "ok";
    case SolveStatus::NotConverged: return "not_converged";
    case SolveStatus::NotPositiveDefinite: return "not_positive_definite";
    case SolveStatus::NumericalError: return "numerical_error";
  }
  return "?";
}

namespace {

using VecMap = Eigen::Map<Eigen::VectorXd>;

class PcgSolver final : public LinearSolver {
 public:
  explicit PcgSolver(const PcgOptions& o) : opt_(o) {
    if (!(o.tolerance > 0.0) || o.max_iterations < 1)
      throw std::invalid_argument("pcg: tolerance must be > 0 and max_iterations >= 1");
  }
  const char* name() const override { return "pcg"; }

  void analyze(const SymCsr& A) override {
    if (A.n % 3 != 0) throw std::invalid_argument("pcg: matrix size must be a multiple of 3");
    n_ = A.n;
    r_.setZero(n_);
    z_.setZero(n_);
    p_.setZero(n_);
    q_.setZero(n_);
    const int nb = n_ / 3;
    diag_.resize(nb);
    inv_.resize(nb);
    for (int b = 0; b < nb; ++b) {
      for (int a = 0; a < 3; ++a) {
        const int o = A.find(3 * b + a, 3 * b);
        if (o < 0) throw std::invalid_argument("pcg: diagonal block missing from the pattern");
        diag_[b][a] = o;
      }
    }
  }

  SolveStatus solve(const SymCsr& A, const double* bptr, double* xptr) override {
    Eigen::Map<const Eigen::VectorXd> b(bptr, n_);
    VecMap x(xptr, n_);
    iterations_ = 0;
    residual_ = 0.0;
    // Block-Jacobi preconditioner: inverse of each 3x3 diagonal block.
    const double* v = A.val.data();
    for (size_t k = 0; k < inv_.size(); ++k) {
      Eigen::Matrix3d D;
      for (int a = 0; a < 3; ++a)
        for (int c = 0; c < 3; ++c) D(a, c) = v[diag_[k][a] + c];
      const double det = D.determinant();
      if (!(det > 0.0) || !std::isfinite(det)) return SolveStatus::NotPositiveDefinite;
      inv_[k] = D.inverse();
    }
    const double bnorm = b.norm();
    if (!std::isfinite(bnorm)) return SolveStatus::NumericalError;
    if (bnorm == 0.0) {
      x.setZero();
      return SolveStatus::Ok;
    }
    if (!x.allFinite()) x.setZero();
    A.multiply(xptr, q_.data());
    r_ = b - q_;
    const double goal = opt_.tolerance * bnorm;
    double rnorm = r_.norm();
    if (rnorm <= goal) {
      residual_ = rnorm / bnorm;
      return SolveStatus::Ok;
    }
    precondition(r_, z_);
    p_ = z_;
    double rz = r_.dot(z_);
    for (int it = 1; it <= opt_.max_iterations; ++it) {
      A.multiply(p_.data(), q_.data());
      const double pq = p_.dot(q_);
      if (!(pq > 0.0)) {
        iterations_ = it;
        return std::isfinite(pq) ? SolveStatus::NotPositiveDefinite : SolveStatus::NumericalError;
      }
      const double alpha = rz / pq;
      x.noalias() += alpha * p_;
      r_.noalias() -= alpha * q_;
      rnorm = r_.norm();
      iterations_ = it;
      if (!std::isfinite(rnorm)) return SolveStatus::NumericalError;
      if (rnorm <= goal) {
        residual_ = rnorm / bnorm;
        return SolveStatus::Ok;
      }
      precondition(r_, z_);
      const double rz_new = r_.dot(z_);
      p_ = z_ + (rz_new / rz) * p_;
      rz = rz_new;
    }
    residual_ = rnorm / bnorm;
    return SolveStatus::NotConverged;
  }

 private:
  void precondition(const Eigen::VectorXd& r, Eigen::VectorXd& z) const {
    for (size_t k = 0; k < inv_.size(); ++k)
      z.segment<3>(3 * k).noalias() = inv_[k] * r.segment<3>(3 * k);
  }

  PcgOptions opt_;
  int n_ = 0;
  Eigen::VectorXd r_, z_, p_, q_;
  std::vector<std::array<int, 3>> diag_;
  std::vector<Eigen::Matrix3d> inv_;
};

}  // namespace

std::unique_ptr<LinearSolver> make_pcg_solver(const PcgOptions& opt) {
  return std::make_unique<PcgSolver>(opt);
}

std::unique_ptr<LinearSolver> make_solver(const std::string& name, const PcgOptions& pcg) {
  if (name == "pcg") return make_pcg_solver(pcg);
  if (name == "cholmod") return make_cholmod_solver(CholmodMode::Simplicial);
  if (name == "cholmod-supernodal") return make_cholmod_solver(CholmodMode::Supernodal);
  throw std::invalid_argument("unknown solver '" + name + "' (pcg, cholmod, cholmod-supernodal)");
}

}  // namespace hapticloth::cloth
