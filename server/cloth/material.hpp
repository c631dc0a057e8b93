// Cloth material: areal density and the three independent in-plane laws (section 3.2).
#pragma once

#include <string>

#include "cloth/curve.hpp"
#include "cloth/surface.hpp"

namespace hapticloth::cloth {

/// Orthotropic membrane material with null Poisson coefficient (section 3.2): weft (uu),
/// warp (vv) and shear (uv) are independent strain-stress curves, each with an optional
/// linear viscosity.
struct Material {
  std::string name;
  double areal_density = 0.0;  ///< kg/m^2
  StrainStressCurve weft;      ///< sigma_uu(eps_uu), N/m
  StrainStressCurve warp;      ///< sigma_vv(eps_vv), N/m
  StrainStressCurve shear;     ///< sigma_uv(eps_uv), N/m, odd
  Surface surface;             ///< what the skin feels (tactile rendering); absent if not given

  bool viscous() const {
    return weft.viscosity > 0.0 || warp.viscosity > 0.0 || shear.viscosity > 0.0;
  }
};

}  // namespace hapticloth::cloth
