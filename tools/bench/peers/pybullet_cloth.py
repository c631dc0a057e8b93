#!/usr/bin/env python3
"""The hanging square in PyBullet's deformable world (RESET_USE_DEFORMABLE_WORLD).

The grid is written as an OBJ (the scene's vertices and alternating diagonals) and loaded with
loadSoftBody as a mass-spring cloth: one spring per mesh edge with stiffness k = 2004 / 1.5 N/m (on
this grid the edge springs give C11 = C22 = 1.5 k = the warp stiffness, isotropic, Poisson coupling
C12 = 0.5 k), no bending springs, no spring damping. Total mass 0.081 kg, which Bullet spreads
evenly over the 529 nodes. The 23 nodes of the top row are anchored to the world
(createSoftBodyAnchor). The deformable world has no air or velocity damping for soft bodies (its
damping terms act on spring elongation rates only), so the cloth is undamped here. No contacts
(nothing else in the world, self-collision off).
"""

import common  # noqa: I001  (sets the thread variables before numpy is imported)

import os
import tempfile

import numpy as np
import pybullet as p


class Sim:
    def __init__(self, dt, k_scale, obj):
        self.cid = p.connect(p.DIRECT)
        p.resetSimulation(p.RESET_USE_DEFORMABLE_WORLD, physicsClientId=self.cid)
        p.setGravity(*common.GRAVITY, physicsClientId=self.cid)   # before loading: Bullet adds
        p.setTimeStep(dt, physicsClientId=self.cid)                # a gravity force per body then
        self.body = p.loadSoftBody(
            obj, basePosition=[0, 0, 0], scale=1.0, mass=common.MASS,
            useMassSpring=1, useBendingSprings=0, useNeoHookean=0,
            springElasticStiffness=common.K_ISO * k_scale / 1.5, springDampingStiffness=0.0,
            springDampingAllDirections=0, springBendingStiffness=0.0,
            useSelfCollision=0, useFaceContact=0, frictionCoeff=0.0, collisionMargin=0.001,
            physicsClientId=self.cid)
        rest = self.positions()
        perm = common.match_order(rest)
        for v in common.PINNED:
            p.createSoftBodyAnchor(self.body, int(perm[v]), -1, -1, physicsClientId=self.cid)

    def step(self):
        p.stepSimulation(physicsClientId=self.cid)

    def positions(self):
        _, pos = p.getMeshData(self.body, -1, flags=p.MESH_DATA_SIMULATION_MESH,
                               physicsClientId=self.cid)
        return np.asarray(pos, dtype=float)

    def close(self):
        p.disconnect(physicsClientId=self.cid)


def pybullet_version():
    try:
        from importlib.metadata import version
        return version("pybullet")
    except Exception:
        return "unknown"


def main():
    args = common.parser(__doc__.splitlines()[1]).parse_args()
    tmp = tempfile.mkdtemp(prefix="peers-pybullet-")
    obj = os.path.join(tmp, "hanging_square.obj")
    common.write_obj(obj)
    mapping = (f"mass-spring on the mesh edges, k {common.K_ISO / 1.5:.4g} N/m per spring (grid C11 = 1.5 k ="
               f" {common.K_ISO:g} N/m isotropic, C12 = 0.5 k); mass {common.MASS:g} kg even over 529 nodes;"
               " top row anchored")
    variants = [{
        "name": "deformable mass-spring", "mapping": mapping, "extra_dts_ms": [0.1],
        "short": f"edge springs {common.K_ISO / 1.5:.0f} N/m (grid C11 = {common.K_ISO:.0f} N/m isotropic)",
        "notes": "no air damping available for soft bodies: undamped swing (judged by the lowest point"
                 " over the last 1 s); no bending springs; shear 12x ours; 0.1 ms added",
        "make": (lambda dt: Sim(dt, args.k_scale, obj)),
    }]
    try:
        common.run_variants(args, "PyBullet", pybullet_version(), variants)
    finally:
        for f in os.listdir(tmp):
            os.remove(os.path.join(tmp, f))
        os.rmdir(tmp)


if __name__ == "__main__":
    main()
