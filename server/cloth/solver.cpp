// The solvers' names and statuses, and the one place a solver is chosen by name.
#include "cloth/solver.hpp"

#include <stdexcept>
#include <string>

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

const char* to_string(PcgPreconditioner p) {
  return p == PcgPreconditioner::Ssor ? "ssor" : "block-jacobi";
}

std::unique_ptr<LinearSolver> make_solver(const std::string& name, const PcgOptions& pcg) {
  if (name == "pcg") return make_pcg_solver(pcg);
  if (name == "cholmod") return make_cholmod_solver(CholmodMode::Simplicial);
  if (name == "cholmod-supernodal") return make_cholmod_solver(CholmodMode::Supernodal);
  throw std::invalid_argument("unknown solver '" + name + "' (pcg, cholmod, cholmod-supernodal)");
}

}  // namespace hapticloth::cloth
