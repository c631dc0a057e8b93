#!/usr/bin/env python3
"""The hanging square in Newton (warp on device "cpu"): one row per cloth solver.

The mesh is the scene's own grid (alternating diagonals), masses lumped from 0.324 kg/m^2 by
add_cloth_mesh, the top row made kinematic (mass 0, not ACTIVE). No bending (edge stiffness 0), no
contacts (no shapes, particle radius 0, no self-contact). Air damping: after every step the particle
velocities are scaled by exp(-1.54 dt), the scene's decay rate, with one small warp kernel.

  VBD          SolverVBD (vertex block descent, implicit Euler), stable Neo-Hookean membrane with
               Lame mu = 1002 N/m, lambda = 0: tension per unit strain 2 mu = 2004 N/m, isotropic.
  XPBD         SolverXPBD, one distance constraint per mesh edge with stiffness k = 2004 / 1.5
               N/m (on this grid the edge springs give C11 = C22 = 1.5 k), compliance 1 / k. The
               solver sums the corrections of all constraints on a particle (Jacobi) and its
               relaxation options do not act on springs.
  SemiImplicit SolverSemiImplicit (symplectic Euler), the same membrane as VBD (k_mu 1002,
               k_lambda 1002: Newton's raw stable-Neo-Hookean lambda, i.e. Lame lambda 0).
  Style3D      SolverStyle3D (projective dynamics / implicit Euler, Baraff-Witkin anisotropic
               stretch): weft 399.4, warp 2003.9, shear 53.4 N/m, the scene's own small-strain values.
"""

import common  # noqa: I001  (sets the thread variables before numpy is imported)

import math

import numpy as np
import warp as wp

wp.config.quiet = True
wp.config.verbose = False

import newton  # noqa: E402
from newton.solvers import style3d  # noqa: E402

DEVICE = "cpu"
ITERATIONS = 10            # VBD / XPBD / Style3D iterations per step (Newton's examples use 10)


@wp.kernel
def scale_velocities(qd: wp.array[wp.vec3], factor: float):
    i = wp.tid()
    qd[i] = qd[i] * factor


def build(kind, k_scale):
    builder = newton.ModelBuilder(gravity=wp.vec3(*common.GRAVITY))
    verts = [wp.vec3(*v) for v in common.VERTS]
    indices = common.TRIS.ravel().tolist()
    mu = 0.5 * common.K_ISO * k_scale
    common_kw = dict(pos=wp.vec3(0.0, 0.0, 0.0), rot=wp.quat_identity(), vel=wp.vec3(0.0, 0.0, 0.0),
                     vertices=verts, indices=indices, density=common.DENSITY, particle_radius=0.0, scale=1.0)
    if kind == "Style3D":
        newton.solvers.SolverStyle3D.register_custom_attributes(builder)
        style3d.add_cloth_mesh(
            builder, **common_kw,
            tri_aniso_ke=wp.vec3(common.K_WEFT * k_scale, common.K_WARP * k_scale, common.K_SHEAR * k_scale),
            edge_aniso_ke=wp.vec3(0.0, 0.0, 0.0), tri_kd=0.0, edge_kd=0.0)
    elif kind == "XPBD":
        builder.add_cloth_mesh(**common_kw, tri_ke=0.0, tri_ka=0.0, tri_kd=0.0, edge_ke=0.0, edge_kd=0.0)
        k = common.K_ISO * k_scale / 1.5
        for a, b in common.EDGES:
            builder.add_spring(int(a), int(b), k, 0.0, 0.0)
    else:  # VBD and SemiImplicit: the triangle membrane
        ka = 0.0 if kind == "VBD" else mu
        builder.add_cloth_mesh(**common_kw, tri_ke=mu, tri_ka=ka, tri_kd=0.0, edge_ke=0.0, edge_kd=0.0)
    flags = newton.ParticleFlags.ACTIVE
    for v in common.PINNED:
        builder.particle_mass[int(v)] = 0.0
        builder.particle_flags[int(v)] = builder.particle_flags[int(v)] & ~flags
    if kind == "VBD":
        builder.color()
    return builder.finalize(device=DEVICE)


class Sim:
    def __init__(self, kind, dt, k_scale, xpbd_relaxation=None):
        with wp.ScopedDevice(DEVICE):
            self.model = build(kind, k_scale)
            self.model.particle_grid = None
            if kind == "VBD":
                self.solver = newton.solvers.SolverVBD(self.model, iterations=ITERATIONS)
            elif kind == "XPBD":
                kw = {} if xpbd_relaxation is None else {"soft_body_relaxation": xpbd_relaxation}
                self.solver = newton.solvers.SolverXPBD(self.model, iterations=ITERATIONS, **kw)
            elif kind == "SemiImplicit":
                self.solver = newton.solvers.SolverSemiImplicit(self.model, enable_tri_contact=False)
            else:
                self.solver = newton.solvers.SolverStyle3D(
                    self.model, config=newton.solvers.SolverStyle3D.Config(iterations=ITERATIONS))
                self.solver.collision = None   # the documented switch: no (self-)contact
            self.s0, self.s1 = self.model.state(), self.model.state()
            self.control = self.model.control()
        self.dt = dt
        self.decay = math.exp(-common.AIR_DECAY * dt)
        self.n = self.model.particle_count
        self.cur = self.s0
        # Replay each step from a CPU graph where the solver's step is launches only (as Newton's
        # examples do): one graph s0 -> s1, one s1 -> s0. Style3D's PCG takes its dot products on
        # the host between launches, which a CPU graph cannot record: it runs eagerly.
        self.graphs = None
        if kind != "Style3D":
            graphs = []
            for a, b in ((self.s0, self.s1), (self.s1, self.s0)):
                with wp.ScopedCapture(device=DEVICE) as cap:
                    self._step(a, b)
                graphs.append(cap.graph)
            self.graphs = graphs
        self.k = 0

    def _step(self, a, b):
        a.clear_forces()
        self.solver.step(a, b, self.control, None, self.dt)
        wp.launch(scale_velocities, dim=self.n, inputs=[b.particle_qd, self.decay], device=DEVICE)

    def step(self):
        a, b = (self.s0, self.s1) if self.k % 2 == 0 else (self.s1, self.s0)
        if self.graphs:
            wp.capture_launch(self.graphs[self.k % 2])
        else:
            self._step(a, b)
        self.cur = b
        self.k += 1

    def positions(self):
        return self.cur.particle_q.numpy()


def main():
    args = common.parser(__doc__.splitlines()[1]).parse_args()
    ks = args.k_scale
    damping = f"velocities x exp(-{common.AIR_DECAY:.3f} dt) after each step"
    short = {
        "VBD": f"Neo-Hookean membrane, mu {0.5 * common.K_ISO:.0f} N/m, lambda 0 ({common.K_ISO:.0f} N/m isotropic)",
        "XPBD": f"edge constraints {common.K_ISO / 1.5:.0f} N/m (grid C11 = {common.K_ISO:.0f} N/m isotropic)",
        "SemiImplicit": "membrane as VBD",
        "Style3D": f"anisotropic {common.K_WEFT:.0f} / {common.K_WARP:.0f} / {common.K_SHEAR:.0f} N/m (ours, linear)",
    }
    rows = [
        ("VBD", f"stable Neo-Hookean membrane, Lame mu {0.5 * common.K_ISO:g} N/m, lambda 0"
                f" (2 mu = {common.K_ISO:g} N/m isotropic); {ITERATIONS} iterations; {damping}",
         "implicit Euler by vertex block descent; no bending; shear 19x ours", []),
        ("XPBD", f"edge distance constraints, k {common.K_ISO / 1.5:.4g} N/m each (grid C11 = 1.5 k ="
                 f" {common.K_ISO:g} N/m), compliance 1/k; {ITERATIONS} iterations; {damping}",
         "no bending; springs give Poisson coupling C12 = 0.5 k and shear 12x ours; Newton's XPBD sums the"
         " constraint corrections per particle (Jacobi) without averaging", []),
        ("SemiImplicit", f"stable Neo-Hookean membrane as VBD (k_mu {0.5 * common.K_ISO:g}, k_lambda"
                         f" {0.5 * common.K_ISO:g} = Lame lambda 0); {damping}",
         "explicit (symplectic Euler); 0.1 ms added", [0.1]),
        ("Style3D", f"anisotropic stretch weft {common.K_WEFT:g}, warp {common.K_WARP:g}, shear"
                    f" {common.K_SHEAR:g} N/m (our small-strain values); {ITERATIONS} iterations; {damping}",
         "projective dynamics; its velocity update also multiplies by 0.998 every step (extra damping,"
         " 2/s at 1 ms); bending 0", []),
    ]
    variants = []
    for kind, mapping, notes, extra in rows:
        variants.append({
            "name": kind, "mapping": mapping, "notes": notes, "extra_dts_ms": extra, "short": short[kind],
            "make": (lambda dt, k=kind: Sim(k, dt, ks)),
            # Kernels compile (or load from the kernel cache) on first use: not in the timings.
            "warmup": (lambda k=kind: Sim(k, 1e-3, ks).step()),
        })
    version = f"newton {newton.__version__}, warp {wp.__version__}"
    common.run_variants(args, "Newton", version, variants)


if __name__ == "__main__":
    main()
