#include <suitesparse/cholmod.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <vector>

#include "cloth/solver.hpp"

namespace hapticloth::cloth {

namespace {

// CHOLMOD sparse Cholesky with the fill-reducing permutation applied by us.
//
// cholmod_factorize copies A into a permuted temporary on every call unless the ordering is
// natural and only the lower triangle is used. So analyze() asks CHOLMOD for its ordering once
// (AMD/METIS), builds the permuted matrix B = P A P^T with a gather map, and analyses B with the
// natural ordering. solve() gathers the values into B, factorizes B numerically (LL^T, so an
// indefinite matrix is reported, not factored with negative pivots) and solves with permuted
// vectors. The simplicial path refactors with cholmod_rowfac and solves with its own triangular
// sweeps, because cholmod_factorize and cholmod_solve2 allocate on every call: no allocation
// after the first solve. The supernodal path uses cholmod_factorize and cholmod_solve2.
class CholmodSolver final : public LinearSolver {
 public:
  explicit CholmodSolver(CholmodMode mode) : mode_(mode) {
    cholmod_start(&c_);
    c_.print = 0;  // report through status codes, not stdout
    c_.error_handler = nullptr;
    c_.final_asis = 0;
    c_.final_ll = 1;
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
    n_ = A.n;
    if (L_) cholmod_free_factor(&L_, &c_);
    // 1. CHOLMOD's fill-reducing ordering of A.
    cholmod_sparse hdr = header(A.n, A.rowptr.data(), A.col.data(), A.val.data(), 1);
    cholmod_factor* L0 = cholmod_analyze(&hdr, &c_);
    if (!L0 || c_.status != CHOLMOD_OK)
      throw std::runtime_error("cholmod_analyze failed with status " + std::to_string(c_.status));
    perm_.assign(static_cast<const int*>(L0->Perm), static_cast<const int*>(L0->Perm) + n_);
    cholmod_free_factor(&L0, &c_);
    // Dense rows (the fingertip proxies, coupled to every vertex) go last, where they add no
    // fill-in beyond themselves. AMD does this on its own; a nested-dissection ordering (METIS,
    // which CHOLMOD picks when it gives less fill) may not, and then the factor fills in.
    const double dense = std::max(16.0, 10.0 * std::sqrt(static_cast<double>(n_)));
    std::stable_partition(perm_.begin(), perm_.end(),
                          [&](int r) { return A.rowptr[r + 1] - A.rowptr[r] <= dense; });
    std::vector<int> inv(n_);
    for (int i = 0; i < n_; ++i) inv[perm_[i]] = i;

    // 2. B = P A P^T: column j of B is column perm[j] of A with rows renumbered.
    bp_.assign(n_ + 1, 0);
    bi_.resize(A.nnz());
    gather_.resize(A.nnz());
    std::vector<std::pair<int, int>> colbuf;
    for (int j = 0; j < n_; ++j) {
      const int oc = perm_[j];
      colbuf.clear();
      for (int k = A.rowptr[oc]; k < A.rowptr[oc + 1]; ++k) colbuf.push_back({inv[A.col[k]], k});
      std::sort(colbuf.begin(), colbuf.end());
      int o = bp_[j];
      for (const auto& [row, src] : colbuf) {
        bi_[o] = row;
        gather_[o] = src;
        ++o;
      }
      bp_[j + 1] = o;
    }
    bx_.assign(A.nnz(), 0.0);
    pb_.assign(n_, 0.0);
    B_ = header(n_, bp_.data(), bi_.data(), bx_.data(), 1);
    factored_ = false;

    // 3. Symbolic analysis of B in its natural order.
    c_.nmethods = 1;
    c_.method[0].ordering = CHOLMOD_NATURAL;
    c_.postorder = 0;
    L_ = cholmod_analyze(&B_, &c_);
    if (!L_ || c_.status != CHOLMOD_OK)
      throw std::runtime_error("cholmod_analyze (natural) failed with status " +
                               std::to_string(c_.status));
  }

  SolveStatus solve(const SymCsr& A, const double* b, double* x) override {
    iterations_ = 1;
    residual_ = 0.0;
    const double* v = A.val.data();
    for (size_t k = 0; k < gather_.size(); ++k) bx_[k] = v[gather_[k]];
    // Numeric factorization; the symbolic analysis is reused.
    const bool simplicial = factored_ && !L_->is_super;
    int ok;
    if (simplicial) {
      double beta[2] = {0.0, 0.0};
      ok = cholmod_rowfac(&B_, nullptr, beta, 0, L_->n, L_, &c_);
    } else {
      ok = cholmod_factorize(&B_, L_, &c_);
      factored_ = ok && c_.status == CHOLMOD_OK;
    }
    if (c_.status == CHOLMOD_NOT_POSDEF || (ok && L_->minor < L_->n)) {
      factored_ = false;  // L holds a partial factor: start again from cholmod_factorize
      return SolveStatus::NotPositiveDefinite;
    }
    if (!ok || c_.status != CHOLMOD_OK) {
      factored_ = false;
      return SolveStatus::NumericalError;
    }
    return substitute(b, x);
  }

  SolveStatus resolve(const SymCsr& A, const double* b, double* x) override {
    if (!factored_) return solve(A, b, x);
    iterations_ = 1;
    return substitute(b, x);
  }

 private:
  // x from the factor of the last solve.
  SolveStatus substitute(const double* b, double* x) {
    for (int i = 0; i < n_; ++i) pb_[i] = b[perm_[i]];
    if (!L_->is_super && L_->is_ll) {
      solve_simplicial_ll(pb_.data());
      for (int i = 0; i < n_; ++i) x[perm_[i]] = pb_[i];
      return SolveStatus::Ok;
    }
    cholmod_dense rhs;
    std::memset(&rhs, 0, sizeof(rhs));
    rhs.nrow = rhs.d = rhs.nzmax = static_cast<size_t>(n_);
    rhs.ncol = 1;
    rhs.x = pb_.data();
    rhs.xtype = CHOLMOD_REAL;
    rhs.dtype = CHOLMOD_DOUBLE;
    if (!cholmod_solve2(CHOLMOD_A, L_, &rhs, nullptr, &X_, nullptr, &Y_, &E_, &c_))
      return SolveStatus::NumericalError;
    const double* y = static_cast<const double*>(X_->x);
    for (int i = 0; i < n_; ++i) x[perm_[i]] = y[i];
    return SolveStatus::Ok;
  }

  // L L^T y = b in place, on the simplicial factor (columns with the diagonal first).
  void solve_simplicial_ll(double* y) const {
    const int* Lp = static_cast<const int*>(L_->p);
    const int* Li = static_cast<const int*>(L_->i);
    const int* Lnz = static_cast<const int*>(L_->nz);
    const double* Lx = static_cast<const double*>(L_->x);
    for (int j = 0; j < n_; ++j) {
      const int p0 = Lp[j], p1 = Lp[j] + Lnz[j];
      const double yj = (y[j] /= Lx[p0]);
      for (int q = p0 + 1; q < p1; ++q) y[Li[q]] -= Lx[q] * yj;
    }
    for (int j = n_ - 1; j >= 0; --j) {
      const int p0 = Lp[j], p1 = Lp[j] + Lnz[j];
      double s = y[j];
      for (int q = p0 + 1; q < p1; ++q) s -= Lx[q] * y[Li[q]];
      y[j] = s / Lx[p0];
    }
  }

  // A cholmod_sparse header over CSC arrays (not owned). Our CSR of a symmetric matrix is its
  // CSC; stype > 0 uses the upper triangle, stype < 0 the lower one.
  static cholmod_sparse header(int n, const int* p, const int* i, const double* x, int stype) {
    cholmod_sparse h;
    std::memset(&h, 0, sizeof(h));
    h.nrow = h.ncol = static_cast<size_t>(n);
    h.nzmax = static_cast<size_t>(p[n]);
    h.p = const_cast<int*>(p);
    h.i = const_cast<int*>(i);
    h.x = const_cast<double*>(x);
    h.stype = stype;
    h.itype = CHOLMOD_INT;
    h.xtype = CHOLMOD_REAL;
    h.dtype = CHOLMOD_DOUBLE;
    h.sorted = 1;
    h.packed = 1;
    return h;
  }

  CholmodMode mode_;
  cholmod_common c_;
  cholmod_factor* L_ = nullptr;
  cholmod_dense *X_ = nullptr, *Y_ = nullptr, *E_ = nullptr;
  int n_ = 0;
  std::vector<int> perm_;            // B row/col i is A row/col perm_[i]
  std::vector<int> bp_, bi_, gather_;
  std::vector<double> bx_, pb_;
  cholmod_sparse B_;
  bool factored_ = false;  // L_ holds a valid numeric factor of B's pattern
};

}  // namespace

std::unique_ptr<LinearSolver> make_cholmod_solver(CholmodMode mode) {
  return std::make_unique<CholmodSolver>(mode);
}

}  // namespace hapticloth::cloth
