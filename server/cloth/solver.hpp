// Linear solvers for the symmetric positive definite system of eq. 9, behind one interface.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "cloth/sparse.hpp"

namespace hapticloth::cloth {

class WorkerPool;

enum class SolveStatus { Ok, NotConverged, NotPositiveDefinite, NumericalError };
const char* to_string(SolveStatus s);

/// Contract: analyze() is called once per sparsity pattern and may allocate; solve() is called
/// every step with the same pattern (values change) and allocates nothing after its first call.
class LinearSolver {
 public:
  virtual ~LinearSolver() = default;
  virtual const char* name() const = 0;
  /// A second thread to share the work with (the integrator's assembly pool), or none. The
  /// solver uses it only inside the caller's run; results do not depend on it.
  virtual void use_pool(WorkerPool* pool) { (void)pool; }
  /// Symbolic work that depends on the pattern only.
  virtual void analyze(const SymCsr& A) = 0;
  /// Solves A x = b. On entry x holds a starting guess (iterative solvers use it).
  virtual SolveStatus solve(const SymCsr& A, const double* b, double* x) = 0;
  /// Solves again with the matrix of the last solve(), unchanged since: a direct solver reuses
  /// its factor, an iterative one its copy of the matrix and its preconditioner.
  virtual SolveStatus resolve(const SymCsr& A, const double* b, double* x) { return solve(A, b, x); }
  /// Solves A x = b where A differs from the matrix of the last solve() only in the listed
  /// block rows (3x3 blocks; each row once) and, by symmetry, their columns: the fingertip
  /// contacts' re-solves, whose springs touch a few vertices and the proxies. An iterative
  /// solver reloads and re-preconditions those rows only; a direct one factors again.
  virtual SolveStatus solve_changed(const SymCsr& A, const int* block_rows, int count,
                                    const double* b, double* x) {
    (void)block_rows;
    (void)count;
    return solve(A, b, x);
  }
  /// As solve_changed, but solving only the rows that the changed ones hang on, with the rest of
  /// x held: PCG's dense block of the hub rows (the fingertip proxies) and the vertices they
  /// reach most strongly (at most 24 nodes in all; a vertex left out of it is held with the
  /// rest). One dense block solve, where a whole re-solve takes as many iterations as a step; the
  /// contacts decide on that candidate, and the integrator solves the whole system after
  /// (resolve). Only solvers whose settles_locally() is true (after analyze(): PCG with hub
  /// rows in the pattern) implement it.
  virtual SolveStatus settle_changed(const SymCsr& A, const int* block_rows, int count,
                                     const double* b, double* x) {
    return solve_changed(A, block_rows, count, b, x);
  }
  virtual bool settles_locally() const { return false; }
  /// A residual size that counts as converged whatever |b| is: an iterative solve stops at
  /// |b - A x| <= tolerance max(|b|, scale) (a direct one ignores it). 0, the default: relative
  /// to |b| alone. The integrator gives the norm of the weight's impulse over its step
  /// (Integrator::weight_impulse), so that a cloth at rest, whose right-hand side is a thousandth
  /// of that, is not solved to a millionth of its weight.
  void set_residual_scale(double scale) { residual_scale_ = scale; }
  double residual_scale() const { return residual_scale_; }
  /// Iterations of the last solve (1 for a direct solve).
  int iterations() const { return iterations_; }
  /// Relative residual |b - A x| / |b| of the last solve (iterative solvers).
  double residual() const { return residual_; }
  /// Solves whose single-precision matrix copy stalled above the tolerance and were solved
  /// again in double precision (PCG with PcgOptions::single_precision_matrix), since analyze().
  int precision_fallbacks() const { return precision_fallbacks_; }
  /// Sweeps of a part of the matrix that the helper thread (use_pool) ran, since analyze(): 0
  /// when it never had one, or never came in time.
  std::uint64_t helper_sweeps() const { return helper_sweeps_; }

 protected:
  int iterations_ = 0;
  double residual_ = 0.0;
  int precision_fallbacks_ = 0;
  std::uint64_t helper_sweeps_ = 0;
  double residual_scale_ = 0.0;
};

/// The PCG's preconditioner. Both treat the fingertip proxies with the vertices they touch as
/// one dense block (PcgOptions::hub_block).
enum class PcgPreconditioner {
  /// The 3x3 diagonal blocks' inverses: cheap, but the cloth's smooth modes converge slowly: a
  /// correction moves one vertex an iteration.
  BlockJacobi,
  /// Symmetric block Gauss-Seidel (SSOR with omega = 1) by Eisenstat's trick: an iteration reads
  /// the matrix once, as block-Jacobi's does, in two sweeps, and a sweep carries a correction
  /// across the cloth, so it takes a fraction of block-Jacobi's iterations (docs/performance.md,
  /// 'Performance of the step').
  Ssor,
};
const char* to_string(PcgPreconditioner p);

struct PcgOptions {
  double tolerance = 1e-6;  ///< relative residual |r| / |b|
  int max_iterations = 500;
  /// Keep the PCG's copy of the matrix in single precision (products still accumulate in
  /// double). Halves the memory each iteration streams; the solve then meets `tolerance` for
  /// a matrix within float rounding (relative 6e-8) of the assembled one, so use it only with
  /// tolerances well above that (the scenes use 1e-3).
  bool single_precision_matrix = false;
  /// Precondition the hub rows (block rows far longer than a mesh's: the fingertip proxies)
  /// together with the nodes their non-zero blocks reach as one dense block (Cholesky, at most
  /// 24 nodes), and every other node by its 3x3 diagonal block.
  bool hub_block = true;
  PcgPreconditioner preconditioner = PcgPreconditioner::Ssor;
  /// SSOR's relaxation factor omega in [1, 2): the sweeps divide by D / omega on the cloth's
  /// rows (the fingertips' dense block is taken whole). Over-relaxing helps a free cloth on a
  /// fine mesh and hurts a pinched one (docs/performance.md, 'Performance of the step'), so the
  /// default is 1.
  double ssor_omega = 1.0;
};

/// Preconditioned conjugate gradients on Eigen vectors, with an SSOR or 3x3 block-Jacobi
/// preconditioner (plus the hub block, see PcgOptions), exactly-zero blocks left out of the
/// product, warm start from the guess in x, and preallocated workspace (Eigen's
/// ConjugateGradient allocates its work vectors on every call, which the 1 kHz path must not).
std::unique_ptr<LinearSolver> make_pcg_solver(const PcgOptions& opt);

enum class CholmodMode { Auto, Simplicial, Supernodal };
/// CHOLMOD sparse Cholesky: symbolic analysis (fill-reducing ordering) once per pattern,
/// numeric factorization every solve.
std::unique_ptr<LinearSolver> make_cholmod_solver(CholmodMode mode = CholmodMode::Simplicial);

/// "pcg" or "cholmod"; throws std::invalid_argument otherwise.
std::unique_ptr<LinearSolver> make_solver(const std::string& name, const PcgOptions& pcg);

}  // namespace hapticloth::cloth
