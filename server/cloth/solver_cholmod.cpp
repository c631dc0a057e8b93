#include <suitesparse/cholmod.h>

#include <cstring>
#include <stdexcept>

#include "cloth/solver.hpp"

namespace hapticloth::cloth {

namespace {

class CholmodSolver final : public LinearSolver {
 public:
  explicit CholmodSolver(CholmodMode mode) : mode_(mode) {
    cholmod_start(&c_);
    c_.print = 0;  // report through status codes, not stdout
    c_.error_handler = nullptr;
    switch (mode) {
      case CholmodMode::Auto: c_.supernodal = CHOLMOD_AUTO; break;
      case CholmodMode::Simplicial: c_.supernodal = CHOLMOD_SIMPLICIAL; break;
      case CholmodMode::Supernodal: c_.supernodal = CHOLMOD_SUPERNODAL; break;
    }
  }
  ~CholmodSolver() override {
    if (X_) cholmod_free_dense(&X_, &c_);
    if (Y_) cholmod_free_dense(&Y_, &c_);
    if (E_) cholmod_free_dense(&E_, &c_);
    if (L_) cholmod_free_factor(&L_, &c_);
    cholmod_finish(&c_);
  }
  const char* name() const override {
    return mode_ == CholmodMode::Supernodal ? "cholmod-supernodal" : "cholmod";
  }

  void analyze(const SymCsr& A) override {
    if (L_) cholmod_free_factor(&L_, &c_);
    set_header(A);
    L_ = cholmod_analyze(&A_, &c_);
    if (!L_ || c_.status != CHOLMOD_OK)
      throw std::runtime_error("cholmod_analyze failed with status " + std::to_string(c_.status));
    n_ = A.n;
  }

  SolveStatus solve(const SymCsr& A, const double* b, double* x) override {
    iterations_ = 1;
    residual_ = 0.0;
    set_header(A);
    // Numeric factorization; the symbolic analysis (ordering, elimination tree) is reused.
    const int ok = cholmod_factorize(&A_, L_, &c_);
    if (c_.status == CHOLMOD_NOT_POSDEF || (ok && L_->minor < L_->n))
      return SolveStatus::NotPositiveDefinite;
    if (!ok || c_.status != CHOLMOD_OK) return SolveStatus::NumericalError;
    cholmod_dense B;
    std::memset(&B, 0, sizeof(B));
    B.nrow = B.d = B.nzmax = static_cast<size_t>(n_);
    B.ncol = 1;
    B.x = const_cast<double*>(b);
    B.xtype = CHOLMOD_REAL;
    B.dtype = CHOLMOD_DOUBLE;
    // cholmod_solve2 reuses X, Y and E once they exist: no allocation after the first solve.
    if (!cholmod_solve2(CHOLMOD_A, L_, &B, nullptr, &X_, nullptr, &Y_, &E_, &c_))
      return SolveStatus::NumericalError;
    std::memcpy(x, X_->x, sizeof(double) * n_);
    return SolveStatus::Ok;
  }

 private:
  // A cholmod_sparse header over our arrays: our CSR of a symmetric matrix is its CSC.
  void set_header(const SymCsr& A) {
    std::memset(&A_, 0, sizeof(A_));
    A_.nrow = A_.ncol = static_cast<size_t>(A.n);
    A_.nzmax = static_cast<size_t>(A.nnz());
    A_.p = const_cast<int*>(A.rowptr.data());
    A_.i = const_cast<int*>(A.col.data());
    A_.x = const_cast<double*>(A.val.data());
    A_.stype = 1;  // use the upper triangle; the lower one is ignored
    A_.itype = CHOLMOD_INT;
    A_.xtype = CHOLMOD_REAL;
    A_.dtype = CHOLMOD_DOUBLE;
    A_.sorted = 1;
    A_.packed = 1;
  }

  CholmodMode mode_;
  cholmod_common c_;
  cholmod_sparse A_;
  cholmod_factor* L_ = nullptr;
  cholmod_dense *X_ = nullptr, *Y_ = nullptr, *E_ = nullptr;
  int n_ = 0;
};

}  // namespace

std::unique_ptr<LinearSolver> make_cholmod_solver(CholmodMode mode) {
  return std::make_unique<CholmodSolver>(mode);
}

}  // namespace hapticloth::cloth
