#!/usr/bin/env python3
"""The hanging square in MuJoCo: a flexcomp grid (dim 2) of 23 x 23 points, top row pinned.

Membrane: 2D flex elasticity (elastic2d="stretch": Saint Venant-Kirchhoff membrane, no bending) with
poisson 0 and young * thickness = the warp stiffness, so tension per unit strain is 2003.9 N/m in
every direction. Air damping: dof damping m_i * 1.54 N s/m on each vertex's three slide joints (the
same velocity decay as the scene's air damping). Contacts (with anything, and self-contact) off.
Variants: the discrete integrator (implicit in position, the documented one for stiff flexes) with
the Newton and CG solvers, and Euler (flex elasticity explicit).
"""

import common  # noqa: I001  (sets the thread variables before numpy is imported)

import numpy as np
import mujoco

THICKNESS = 1e-3   # m; only the product young * thickness enters a membrane without bending


def xml(dt, integrator, solver, k_scale):
    young = common.K_ISO * k_scale / THICKNESS
    # Points are laid out centred on the flexcomp's frame: x, y in [-0.25, 0.25], z = 0.
    return f"""
<mujoco model="hanging_square">
  <option timestep="{dt}" gravity="0 0 -9.81" integrator="{integrator}" solver="{solver}"
          jacobian="sparse">
    <flag autoreset="disable"/>  <!-- let a diverged state show instead of resetting it -->
  </option>
  <size memory="64M"/>
  <worldbody>
    <flexcomp name="cloth" type="grid" dim="2" count="{common.N} {common.N} 1"
              spacing="{common.H} {common.H} {common.H}" mass="{common.MASS}" radius="0.001"
              inertiabox="0.001">
      <contact contype="0" conaffinity="0" selfcollide="none"/>
      <edge equality="false"/>
      <elasticity young="{young}" poisson="0" thickness="{THICKNESS}" damping="0"
                  elastic2d="stretch"/>
      <pin gridrange="0 {common.N - 1} {common.N - 1} {common.N - 1}"/>
    </flexcomp>
  </worldbody>
</mujoco>"""


class Sim:
    def __init__(self, dt, integrator, solver, k_scale):
        self.m = mujoco.MjModel.from_xml_string(xml(dt, integrator, solver, k_scale))
        self.d = mujoco.MjData(self.m)
        # Air damping: every generated body holds one vertex and three slide joints.
        for j in range(self.m.njnt):
            b = self.m.jnt_bodyid[j]
            self.m.dof_damping[self.m.jnt_dofadr[j]] = self.m.body_mass[b] * common.AIR_DECAY
        mujoco.mj_forward(self.m, self.d)

    def step(self):
        mujoco.mj_step(self.m, self.d)

    def positions(self):
        return self.d.flexvert_xpos


def main():
    args = common.parser(__doc__.splitlines()[1]).parse_args()
    ks = args.k_scale
    mapping = (f"flexcomp grid 23x23, SVK membrane (elastic2d=stretch), young {common.K_ISO / THICKNESS:.4g} Pa"
               f" x thickness {THICKNESS * 1e3:g} mm = {common.K_ISO:g} N/m isotropic, poisson 0;"
               f" mass {common.MASS:g} kg / 529 points (uniform); dof damping m_i x {common.AIR_DECAY:.3f} /s")
    variants = []
    for name, integ, solver, notes, extra in [
        ("discrete/Newton", "discrete", "Newton",
         "implicit in position (h^2 K in the solver metric); no bending; contacts off; shear 19x ours", []),
        ("discrete/CG", "discrete", "CG", "as discrete/Newton with the matrix-free CG solver "
         "(run only when named with --only: it tracks discrete/Newton closely)", []),
        ("Euler", "Euler", "Newton",
         "flex elasticity explicit (semi-implicit Euler), dof damping implicit; 0.1 ms added", [0.1]),
    ]:
        variants.append({"name": name, "mapping": mapping, "notes": notes, "extra_dts_ms": extra,
                         "short": f"SVK membrane, E t = {common.K_ISO:g} N/m isotropic, poisson 0",
                         "optional": name == "discrete/CG",
                         "make": (lambda dt, i=integ, s=solver: Sim(dt, i, s, ks))})
    # Compile once so the first timed run pays no first-use cost.
    Sim(1e-3, "discrete", "Newton", ks).step()
    common.run_variants(args, "MuJoCo", mujoco.__version__, variants)


if __name__ == "__main__":
    main()
