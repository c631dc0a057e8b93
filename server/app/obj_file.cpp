#include "app/obj_file.hpp"
#include "log/input_file.hpp"

#include <cmath>
#include <fstream>
#include <sstream>

#include "app/toml_file.hpp"

namespace hapticloth::app {

ObjMesh load_obj(const std::string& path) {
  if (std::string e = devices::check_input_file(path, devices::kMaxMeshBytes); !e.empty())
    throw ConfigError(e);
  std::ifstream in(path);
  if (!in) throw ConfigError(path + ": cannot open OBJ file");
  ObjMesh m;
  std::string line;
  int lineno = 0;
  auto fail = [&](const std::string& what) {
    throw ConfigError(path + ":" + std::to_string(lineno) + ": " + what);
  };
  while (std::getline(in, line)) {
    ++lineno;
    std::istringstream ls(line);
    std::string tag;
    if (!(ls >> tag) || tag[0] == '#') continue;
    if (tag == "v") {
      double x, y, z;
      if (!(ls >> x >> y >> z) || !std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z))
        fail("vertex needs three finite numbers");
      m.positions.emplace_back(x, y, z);
    } else if (tag == "vt") {
      double u, v;
      if (!(ls >> u >> v) || !std::isfinite(u) || !std::isfinite(v))
        fail("texture coordinate needs two finite numbers");
      m.texcoords.emplace_back(u, v);
    } else if (tag == "f") {
      std::vector<std::array<int, 2>> corners;
      std::string tok;
      while (ls >> tok) {
        int vi = 0, ti = 0;
        const auto s1 = tok.find('/');
        try {
          vi = std::stoi(tok.substr(0, s1));
          if (s1 != std::string::npos) {
            const auto s2 = tok.find('/', s1 + 1);
            const std::string t = tok.substr(s1 + 1, s2 == std::string::npos ? s2 : s2 - s1 - 1);
            if (!t.empty()) ti = std::stoi(t);
          }
        } catch (const std::exception&) {
          fail("bad face corner '" + tok + "'");
        }
        // OBJ indices are 1-based; negative ones count from the end.
        const int np = static_cast<int>(m.positions.size()), nt = static_cast<int>(m.texcoords.size());
        int v0 = vi > 0 ? vi - 1 : np + vi;
        int t0 = ti > 0 ? ti - 1 : (ti < 0 ? nt + ti : -1);
        if (v0 < 0 || v0 >= np) fail("face vertex index " + std::to_string(vi) + " out of range");
        if (ti != 0 && (t0 < 0 || t0 >= nt))
          fail("face texture index " + std::to_string(ti) + " out of range");
        corners.push_back({v0, t0});
      }
      if (corners.size() < 3) fail("face needs at least three corners");
      for (size_t k = 1; k + 1 < corners.size(); ++k) {
        m.triangles.push_back({corners[0][0], corners[k][0], corners[k + 1][0]});
        m.triangle_texcoords.push_back({corners[0][1], corners[k][1], corners[k + 1][1]});
        m.triangle_lines.push_back(lineno);
      }
    }
  }
  if (m.triangles.empty()) throw ConfigError(path + ": no faces");
  return m;
}

}  // namespace hapticloth::app
