#include "cloth/model.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace hapticloth::cloth {

ClothModel build_model(const Mesh& mesh, const Material& material, const std::vector<int>& pins) {
  if (!(material.areal_density > 0.0) || !std::isfinite(material.areal_density))
    throw std::invalid_argument("areal density must be a positive number (kg/m^2)");
  ClothModel m;
  m.material = material;
  m.rest_positions = mesh.positions;
  m.weave_uv = mesh.weave_uv;
  const int nv = static_cast<int>(mesh.positions.size());
  if (mesh.triangles.size() != mesh.weave_uv.size())
    throw std::invalid_argument("mesh: one set of weave coordinates per triangle is required");
  m.mass.assign(nv, 0.0);
  m.vertex_area.assign(nv, 0.0);
  m.elements.reserve(mesh.triangles.size());
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    for (int k = 0; k < 3; ++k) {
      if (tri[k] < 0 || tri[k] >= nv)
        throw std::invalid_argument("triangle " + std::to_string(t) + " has vertex index " +
                                    std::to_string(tri[k]) + " out of range");
    }
    const double uv[3][2] = {{mesh.weave_uv[t][0][0], mesh.weave_uv[t][0][1]},
                             {mesh.weave_uv[t][1][0], mesh.weave_uv[t][1][1]},
                             {mesh.weave_uv[t][2][0], mesh.weave_uv[t][2][1]}};
    ElementRest e;
    try {
      e = make_element(tri[0], tri[1], tri[2], uv);  // eq. 2
    } catch (const std::invalid_argument& err) {
      throw std::invalid_argument("triangle " + std::to_string(t) + ": " + err.what());
    }
    m.elements.push_back(e);
    m.triangles.push_back({tri[0], tri[1], tri[2]});
    for (int k = 0; k < 3; ++k) {
      m.vertex_area[tri[k]] += e.area / 3.0;
      m.mass[tri[k]] += material.areal_density * e.area / 3.0;
    }
    m.total_area += e.area;
  }
  m.total_mass = material.areal_density * m.total_area;

  m.pinned.assign(nv, 0);
  for (int p : pins) {
    if (p < 0 || p >= nv)
      throw std::invalid_argument("pinned vertex " + std::to_string(p) + " out of range [0, " +
                                  std::to_string(nv) + ")");
    m.pinned[p] = 1;
  }
  m.free_index.assign(nv, -1);
  for (int i = 0; i < nv; ++i) {
    if (m.pinned[i]) continue;
    if (m.mass[i] <= 0.0)  // a vertex used by no triangle has no mass: keep it still
    {
      m.pinned[i] = 1;
      continue;
    }
    m.free_index[i] = static_cast<int>(m.free_vertices.size());
    m.free_vertices.push_back(i);
  }

  SystemPattern sys = build_pattern(m, 0);
  m.pattern = std::move(sys.csr);
  m.block_offset = std::move(sys.block_offset);
  m.row_stride = std::move(sys.row_stride);
  m.diag_offset = std::move(sys.diag_offset);
  return m;
}

SystemPattern build_pattern(const ClothModel& m, int proxies) {
  // Block sparsity pattern over free vertices, then the proxies.
  const int nf = m.num_free(), nn = nf + proxies;
  std::vector<std::vector<int>> nbr(nn);
  for (int f = 0; f < nn; ++f) nbr[f].push_back(f);
  for (const auto& e : m.elements) {
    for (int k = 0; k < 3; ++k) {
      const int fk = m.free_index[e.v[k]];
      if (fk < 0) continue;
      for (int l = 0; l < 3; ++l) {
        const int fl = m.free_index[e.v[l]];
        if (fl >= 0) nbr[fk].push_back(fl);
      }
    }
  }
  for (int j = nf; j < nn; ++j)
    for (int f = 0; f < nf; ++f) {
      nbr[f].push_back(j);
      nbr[j].push_back(f);
    }
  SystemPattern sys;
  sys.free_nodes = nf;
  sys.proxies = proxies;
  SymCsr& P = sys.csr;
  P.n = 3 * nn;
  P.block3 = true;
  P.rowptr.assign(P.n + 1, 0);
  sys.row_stride.assign(nn, 0);
  for (int f = 0; f < nn; ++f) {
    auto& b = nbr[f];
    std::sort(b.begin(), b.end());
    b.erase(std::unique(b.begin(), b.end()), b.end());
    sys.row_stride[f] = 3 * static_cast<int>(b.size());
  }
  for (int f = 0; f < nn; ++f)
    for (int a = 0; a < 3; ++a) P.rowptr[3 * f + a + 1] = P.rowptr[3 * f + a] + sys.row_stride[f];
  P.col.resize(P.rowptr[P.n]);
  P.val.assign(P.rowptr[P.n], 0.0);
  for (int f = 0; f < nn; ++f)
    for (int a = 0; a < 3; ++a) {
      int o = P.rowptr[3 * f + a];
      for (int g : nbr[f])
        for (int c = 0; c < 3; ++c) P.col[o++] = 3 * g + c;
    }
  sys.diag_offset.resize(nn);
  for (int f = 0; f < nn; ++f) sys.diag_offset[f] = sys.block(f, f);
  sys.block_offset.resize(m.elements.size());
  for (size_t t = 0; t < m.elements.size(); ++t) {
    const auto& e = m.elements[t];
    for (int k = 0; k < 3; ++k)
      for (int l = 0; l < 3; ++l) {
        const int fk = m.free_index[e.v[k]], fl = m.free_index[e.v[l]];
        sys.block_offset[t][k * 3 + l] = (fk >= 0 && fl >= 0) ? sys.block(fk, fl) : -1;
      }
  }
  return sys;
}

int SystemPattern::block(int a, int b) const {
  const int r = 3 * a;
  const int* lo = csr.col.data() + csr.rowptr[r];
  const int* hi = csr.col.data() + csr.rowptr[r + 1];
  const int* it = std::lower_bound(lo, hi, 3 * b);
  return (it != hi && *it == 3 * b) ? static_cast<int>(it - csr.col.data()) : -1;
}

ClothState rest_state(const ClothModel& model) {
  ClothState s;
  s.x = model.rest_positions;
  s.v.assign(s.x.size(), Vec3::Zero());
  return s;
}

Energies compute_energies(const ClothModel& m, const ClothState& s, const Vec3& gravity) {
  Energies E;
  for (int i = 0; i < m.num_vertices(); ++i) {
    if (m.pinned[i]) continue;
    E.kinetic += 0.5 * m.mass[i] * s.v[i].squaredNorm();
    E.gravity -= m.mass[i] * gravity.dot(s.x[i]);
  }
  for (const auto& e : m.elements)
    E.elastic += element_energy(e, m.material, s.x[e.v[0]], s.x[e.v[1]], s.x[e.v[2]]);
  return E;
}

}  // namespace hapticloth::cloth
