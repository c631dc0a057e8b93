// The Integrator's assembly of eq. 9: the cloth's element and vertex terms into the system,
// formed whole or kept with the changes of the elements that moved (KeptMatrix).
#include "cloth/integrator.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <numeric>
#include <stdexcept>
#include <string>
#include <type_traits>

namespace hapticloth::cloth {

// One pass over the cloth for eq. 9: the element pass (ElementPass, at the instruction level
// in use) forms each element's forces, factored Jacobian, system blocks
// alpha^2 h^2 H_kl + alpha h C_kl and right-hand side h (F - alpha h H v) into the CSR values;
// vertex_terms adds the vertices' own terms. Form KeptChanges: the matrix in hand is kept, and
// only the blocks of the elements whose factors moved are added, as the blocks of the factors'
// change (KeptMatrix). Returns the cloth's energies at the start of the step.
template <class Form>
Integrator::ClothEnergy Integrator::assemble_cloth(const ClothState& s, double h, bool spd) {
  const PassInput in{&model_.material, s.x.data(), s.v.data(), StepFactors{h, alpha_}, viscous_, spd};
  const PassTarget out{A_.val.data(), rhs_.data(), model_.free_index.data(), sys_.block_offset.data(),
                       sys_.row_stride.data()};
  const auto pass = [&](int part) { return pass_->run(Form{}, part, in, out, *kept_, part_refreshed_[part]); };
  const int rest = static_cast<int>(part_free_.size()) - 1;
  if (!pool_) {
    Form::clear(A_.val.data(), 0, static_cast<int>(A_.val.size()));
    const double elastic = pass(rest);
    ClothEnergy e = vertex_terms<Form>(s, h, rest);
    e.elastic = elastic;
    return e;
  }
  // Two threads: the parts at once (disjoint rows), then the separators (the rest); the energy
  // summed in the same order whichever thread took a part. Each part's rows are cleared, and
  // its vertices' terms added, by the thread that assembles its elements, so that they are in
  // its core's cache (zero_spans_, part_free_); the caller takes the rest's first.
  clear_rows<Form>(zero_spans_.back());
  ClothEnergy e = vertex_terms<Form>(s, h, rest);
  auto part = [&](int p) {
    clear_rows<Form>(zero_spans_[p]);
    const double elastic = pass(p);
    part_energy_[p] = vertex_terms<Form>(s, h, p);
    part_energy_[p].elastic = elastic;
  };
  pool_->run(rest, part);
  for (const ClothEnergy& pe : part_energy_) {
    e.elastic += pe.elastic;
    e.kinetic += pe.kinetic;
    e.gravity += pe.gravity;
  }
  e.elastic += pass(rest);
  return e;
}

// Eq. 9's terms of the free vertices of assembly part `part` (part_free_): the lumped mass M
// and air damping on their diagonal blocks, h (M g - c v + f_ext) on their right-hand sides, and
// the external forces' stiffness where it is on. A kept matrix (KeptChanges) holds the mass and
// damping already, and takes only the external stiffness's change. Returns their kinetic and
// gravitational energy.
template <class Form>
Integrator::ClothEnergy Integrator::vertex_terms(const ClothState& s, double h, int part) {
  const double ah = alpha_ * h;
  const double cair = cfg_.air_damping;
  // f_ext(x + dx) ~ f_ext - K dx: K joins H in eq. 9 (alpha^2 h^2 K in the matrix, -alpha h^2 K v
  // on the right).
  const bool held = Form::holds_stiffness(k_ext_held_);
  const bool stiffness_terms = external_stiffness_on || held;
  ClothEnergy e;
  for (int f : part_free_[part]) {
    const int i = model_.free_vertices[f];
    const double mi = model_.mass[i];
    const double ci = cair * model_.vertex_area[i];
    double* dst = A_.val.data() + sys_.diag_offset[f];
    const int stride = sys_.row_stride[f];
    for (int r = 0; r < 3; ++r) Form::add_steady(dst[r * stride + r], mi + ah * ci);
    rhs_.segment<3>(3 * f) += h * (mi * cfg_.gravity - ci * s.v[i] + f_ext_[i]);
    if (external_stiffness_on) rhs_.segment<3>(3 * f) -= ah * h * (k_ext_[i] * s.v[i]);
    if (stiffness_terms) {
      // What A_ holds of it: k_ext_in_matrix_ if it holds any (a kept matrix), else nothing.
      const Mat3 K = external_stiffness_on ? k_ext_[i] : Mat3::Zero();
      Mat3& in_matrix = k_ext_in_matrix_[i];
      const Mat3 dK = held ? Mat3(K - in_matrix) : K;
      in_matrix = K;
      if (!dK.isZero(0.0)) {
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) dst[r * stride + c] += ah * ah * dK(r, c);
        Form::mark(*kept_, part, f);
      }
    }
    e.kinetic += 0.5 * mi * s.v[i].squaredNorm();
    e.gravity -= mi * cfg_.gravity.dot(s.x[i]);
  }
  return e;
}

template <class Form>
void Integrator::clear_rows(const std::vector<std::pair<int, int>>& spans) {
  for (const auto& [begin, end] : spans) Form::clear(A_.val.data(), begin, end);
}

// zero_spans_: for each assembly part, the ranges of A_'s values in the rows its elements reach
// (no other part's reach them), and last the rest (the rows only separators reach, the proxies');
// part_free_: the free vertices of those rows, by part likewise.
void Integrator::plan_clearing(const ElementPartition& partition) {
  const SymCsr& A = sys_.csr;
  const int nb = A.n / 3;
  std::vector<int> owner(nb, -1);
  const int parts = static_cast<int>(partition.parts.size());
  for (int p = 0; p < parts; ++p)
    for (int t : partition.parts[p])
      for (int v : model_.elements[t].v)
        if (model_.free_index[v] >= 0) owner[model_.free_index[v]] = p;
  zero_spans_.assign(parts + 1, {});
  part_free_.assign(parts + 1, {});
  for (int f = 0; f < model_.num_free(); ++f) part_free_[owner[f] < 0 ? parts : owner[f]].push_back(f);
  for (int br = 0; br < nb; ++br) {
    auto& spans = zero_spans_[owner[br] < 0 ? parts : owner[br]];
    const int begin = A.rowptr[3 * br], end = A.rowptr[3 * br + 3];
    if (!spans.empty() && spans.back().second == begin)
      spans.back().second = end;
    else
      spans.push_back({begin, end});
  }
}

// Eq. 9 at state s for the (sub)step h: the matrix formed whole, or kept from the last
// assembly (KeptMatrix::keeps: the same h, alpha and mode) with the changes of the elements
// that moved, the external stiffness and the proxies' springs.
bool Integrator::assemble(const ClothState& s, double h, JacobianMode mode) {
  return kept_->keeps(h, alpha_, mode) ? assemble_as<KeptChanges>(s, h, mode) : assemble_as<WholeMatrix>(s, h, mode);
}

template <class Form>
bool Integrator::assemble_as(const ClothState& s, double h, JacobianMode mode) {
  constexpr bool whole = std::is_same_v<Form, WholeMatrix>;
  rhs_.setZero();
  if constexpr (!whole) take_out_springs(h);  // the last step's springs, added again below
  const ClothEnergy e = assemble_cloth<Form>(s, h, mode == JacobianMode::Spd);
  for (int n : part_refreshed_) timing_.refreshed_elements += n;
  timing_.whole_assemblies += whole;
  const double ke = e.kinetic, e_el = e.elastic, eg = e.gravity;
  energy_old_ = ke + e_el + eg;
  energy_scale_ = ke + std::abs(e_el) + energy_floor_;
  if (cfg_.proxies > 0) {
    assemble_proxies(s, h);
    if constexpr (!whole) mark_proxy_rows();
  }
  k_ext_held_ = external_stiffness_on;
  springs_in_matrix_.assign(springs_.begin(), springs_.end());
  assembled_kept_ = !whole;
  if constexpr (whole) solver_synced_ = false;  // the solver's copy is of another matrix
  const bool ok = rhs_.allFinite() && std::isfinite(energy_old_);
  if (ok)
    kept_->assembled(h, alpha_, mode, whole);
  else
    kept_->invalidate();
  return ok;
}

}  // namespace hapticloth::cloth
