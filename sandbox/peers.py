"""Peer engines on our scenes: pybullet, set up the way the team's anchors (RESULTS.md) were.

Boxes as maximal-coordinate rigid bodies with the scene's masses and half extents, static
planes, friction sqrt(0.5) per body (Bullet multiplies the two coefficients, so every pair gets
0.5), no damping, no sleeping, ``numSolverIterations`` = iterations. Only box-and-plane scenes
are translated. Used by ``sandbox bench`` and ``benchmarks/peer_pybullet.py``; needs the
``peers`` extra.
"""

from __future__ import annotations

import numpy as np

from .errors import SandboxError
from .scene.spec import Scene


def pybullet_world(scene: Scene, iterations: int):
    import pybullet as pb

    cid = pb.connect(pb.DIRECT)
    pb.setGravity(*scene.world.gravity, physicsClientId=cid)
    pb.setTimeStep(scene.world.dt, physicsClientId=cid)
    pb.setPhysicsEngineParameter(numSolverIterations=iterations, physicsClientId=cid)
    mu = float(np.sqrt(0.5))
    for plane in scene.planes:
        shape = pb.createCollisionShape(pb.GEOM_PLANE, planeNormal=list(plane.normal), physicsClientId=cid)
        pid = pb.createMultiBody(0, shape, basePosition=list(np.asarray(plane.normal) * plane.offset),
                                 physicsClientId=cid)
        pb.changeDynamics(pid, -1, lateralFriction=mu, physicsClientId=cid)
    ids, masses, inertias = [], [], []
    for body in scene.bodies:
        if len(body.shapes) != 1 or body.shapes[0].kind != "box":
            raise SandboxError("only box-and-plane scenes are translated to pybullet")
        h = body.shapes[0].half_extents
        shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=list(h), physicsClientId=cid)
        w, x, y, z = body.orientation
        bid = pb.createMultiBody(body.mass, shape, basePosition=list(body.position), baseOrientation=[x, y, z, w],
                                 useMaximalCoordinates=True, physicsClientId=cid)
        pb.changeDynamics(bid, -1, lateralFriction=mu, linearDamping=0.0, angularDamping=0.0,
                          activationState=pb.ACTIVATION_STATE_DISABLE_SLEEPING, physicsClientId=cid)
        ids.append(bid)
        masses.append(body.mass)
        inertias.append(np.diag(body.inertia))
    return pb, cid, ids, np.asarray(masses), np.asarray(inertias)


def pybullet_ke(pb, cid, ids, masses, inertias) -> float:
    ke = 0.0
    for bid, m, inertia in zip(ids, masses, inertias):
        v, w = pb.getBaseVelocity(bid, physicsClientId=cid)
        q = pb.getBasePositionAndOrientation(bid, physicsClientId=cid)[1]
        r = np.asarray(pb.getMatrixFromQuaternion(q)).reshape(3, 3)
        wb = r.T @ np.asarray(w)
        ke += 0.5 * m * np.dot(v, v) + 0.5 * np.dot(wb, inertia * wb)
    return ke
