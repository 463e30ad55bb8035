"""Peer engines on our scenes, behind one small interface, for ``sandbox bench`` and the peer scripts.

A peer is a ``Peer`` in ``PEERS``: its name (the ``engine`` column of the bench tables), the
package that must be importable and the pip extra that installs it, a test of whether a scene
translates faithfully, and a constructor of a ``PeerWorld`` (step, kinetic energy, contact
metrics, a body's position, close) whose numbers follow our metrics' definitions. Adding an
engine means one ``PeerWorld`` class and one ``PEERS`` entry; the bench protocol
(``sandbox/bench/protocol.py``) runs any of them.

pybullet is set up the way the team's anchors (RESULTS.md) were: boxes as maximal-coordinate
rigid bodies with the scene's masses and half extents, static planes, friction sqrt(0.5) per
body (Bullet multiplies the two coefficients, so every pair gets 0.5), no damping, no sleeping,
``numSolverIterations`` = iterations. Only box-and-plane scenes are translated.
Rapier (``rapier3d``, Rust, f32) runs our very scheme from 8 iterations on (below, ours sweeps more
per substep, Settings.step_sweeps): ``num_solver_iterations`` = iterations
substeps of dt / iterations, each with one biased and one relax sweep, soft contacts (30 Hz,
damping ratio 10, twice as stiff against fixed bodies). It is set up as in the team's anchors
(apis.md section 6): cuboids with the scene's masses (solid-box inertia), half-spaces on fixed
bodies, friction 0.5 and restitution 0 combined by AVERAGE, no damping, no sleeping, no CCD,
and a stated number of worker threads (``rapier-t1``, ``rapier-t2``). Its contacts' stored
depths are stale under contact recycling, so ``metrics`` measures them again from the two
body-local points and the poses. ``benchmarks/peer_speed.py`` times every peer against our
solvers, interleaved round by round. Needs the ``peers`` extra.
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass
from typing import Callable, Protocol

import numpy as np

from .errors import SandboxError
from .scene.spec import Scene


class PeerWorld(Protocol):
    """One scene running in a peer engine, measured the way ``World.metrics()`` measures ours."""

    def step(self) -> None: ...

    def kinetic_energy(self) -> float: ...

    def metrics(self) -> dict:
        """``kinetic_energy`` [J], ``contacts`` (points), ``max_penetration`` and ``mean_penetration`` [m]."""
        ...

    def position(self, i: int) -> np.ndarray: ...

    def close(self) -> None: ...


@dataclass(frozen=True)
class Peer:
    name: str  # the engine column of the bench tables
    package: str  # import name that must be found
    extra: str  # pip extra that installs it
    translatable: Callable[[Scene], tuple[bool, str]]  # (True, "") or (False, why: "it <why>")
    open: Callable[[Scene, int], PeerWorld]  # (scene, iterations) -> a running world

    def available(self) -> tuple[bool, str]:
        """Whether the engine can be imported, and if not, why and how to install it."""
        if importlib.util.find_spec(self.package) is None:
            return False, f"{self.package} is not importable (pip install -e '.[{self.extra}]')"
        return True, ""

    def version(self) -> str:
        try:
            from importlib.metadata import version

            return version(self.package)
        except Exception:
            return "unknown"


# ---------------------------------------------------------------------------------------------- pybullet
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


def pybullet_version() -> str:
    return PEERS["pybullet"].version()


def translatable_to_pybullet(scene: Scene) -> tuple[bool, str]:
    """Only scenes that ``pybullet_world`` translates faithfully: dynamic single boxes on planes,
    friction 0.5 and no restitution everywhere (its set-up), no meshes, events or substeps."""
    if scene.meshes:
        return False, "has triangle meshes"
    if scene.events:
        return False, "has timeline events"
    if int(scene.world.substeps) != 1:
        return False, "uses [world] substeps"
    for b in scene.bodies:
        if b.static or len(b.shapes) != 1 or b.shapes[0].kind != "box":
            return False, "has bodies other than dynamic single boxes"
        if abs(b.friction - 0.5) > 1e-9 or b.restitution != 0.0:
            return False, "has friction other than 0.5 or restitution"
    for p in scene.planes:
        if abs(p.friction - 0.5) > 1e-9 or p.restitution != 0.0:
            return False, "has a plane with friction other than 0.5 or restitution"
    return True, ""


class PyBulletWorld:
    """A scene in pybullet (``pybullet_world``), with our metrics' definitions."""

    def __init__(self, scene: Scene, iterations: int):
        self.pb, self.cid, self.ids, self.masses, self.inertias = pybullet_world(scene, iterations)

    def step(self) -> None:
        self.pb.stepSimulation(physicsClientId=self.cid)

    def kinetic_energy(self) -> float:
        return float(pybullet_ke(self.pb, self.cid, self.ids, self.masses, self.inertias))

    def metrics(self) -> dict:
        pts = self.pb.getContactPoints(physicsClientId=self.cid)
        pen = np.array([max(0.0, -p[8]) for p in pts]) if pts else np.zeros(0)
        return {"kinetic_energy": self.kinetic_energy(), "contacts": len(pts),
                "max_penetration": float(pen.max()) if len(pen) else 0.0,
                "mean_penetration": float(pen.mean()) if len(pen) else 0.0}

    def position(self, i: int) -> np.ndarray:
        return np.asarray(self.pb.getBasePositionAndOrientation(self.ids[i], physicsClientId=self.cid)[0])

    def close(self) -> None:
        self.pb.disconnect(physicsClientId=self.cid)


# ---------------------------------------------------------------------------------------------- Rapier
class RapierWorld:
    """A scene in Rapier with ``threads`` worker threads (module docstring), with our metrics' definitions."""

    def __init__(self, scene: Scene, iterations: int, threads: int):
        import rapier3d as r

        translatable, why = translatable_to_pybullet(scene)
        if not translatable:
            raise SandboxError(f"only box-and-plane scenes are translated to Rapier: this one {why}")
        self.world = w = r.PhysicsWorld(gravity=tuple(float(g) for g in scene.world.gravity))
        w.set_num_threads(int(threads))
        w.integration_parameters.dt = float(scene.world.dt)
        w.integration_parameters.num_solver_iterations = int(iterations)
        average = r.CoefficientCombineRule.AVERAGE
        for plane in scene.planes:
            origin = tuple(float(x) for x in np.asarray(plane.normal) * plane.offset)
            w.add_body(r.RigidBody.fixed().translation(origin),
                       colliders=[r.Collider.halfspace(tuple(float(x) for x in plane.normal)).friction(0.5)
                                  .restitution(0.0).friction_combine_rule(average)])
        self.handles = []
        for body in scene.bodies:
            hx, hy, hz = (float(x) for x in body.shapes[0].half_extents)
            qw, qx, qy, qz = (float(x) for x in body.orientation)
            builder = (r.RigidBody.dynamic().translation(tuple(float(x) for x in body.position))
                       .rotation(r.Rotation3.from_quaternion(qw, qx, qy, qz).scaled_axis)
                       .can_sleep(False).ccd_enabled(False))
            collider = r.Collider.cuboid(hx, hy, hz).mass(float(body.mass)).friction(0.5).restitution(0.0) \
                .friction_combine_rule(average)
            self.handles.append(w.add_body(builder, colliders=[collider]))

    def step(self) -> None:
        self.world.step()

    def kinetic_energy(self) -> float:
        bodies = self.world.rigid_bodies
        return float(sum(bodies[h].kinetic_energy() for h in self.handles))

    def contact_points(self):
        """Each contact point now: (normal from collider 1's face, the point on collider 1, the point on
        collider 2 (world) [m], its impulse over the last step [N s]). Depths are recomputed from the
        points: the stored distance goes stale when Rapier recycles a contact."""
        colliders = self.world.colliders
        for pair in self.world.narrow_phase.contact_pairs():
            pose1 = colliders.get(pair.collider1).position
            pose2 = colliders.get(pair.collider2).position
            for m in pair.manifolds:
                n = np.asarray(pose1.rotation.transform_vector(m.local_n1).to_tuple())
                for point in m.points:
                    p1 = np.asarray(pose1.transform_point(point.local_p1).to_tuple())
                    p2 = np.asarray(pose2.transform_point(point.local_p2).to_tuple())
                    yield n, p1, p2, float(point.impulse)

    def metrics(self) -> dict:
        pen = np.asarray([max(0.0, -float(np.dot(p2 - p1, n))) for n, p1, p2, _ in self.contact_points()])
        return {"kinetic_energy": self.kinetic_energy(), "contacts": len(pen),
                "max_penetration": float(pen.max()) if len(pen) else 0.0,
                "mean_penetration": float(pen.mean()) if len(pen) else 0.0}

    def position(self, i: int) -> np.ndarray:
        return np.asarray(self.world.rigid_bodies[self.handles[i]].translation.to_tuple())

    def close(self) -> None:
        self.world.clear()


PEERS = {
    "pybullet": Peer("pybullet", package="pybullet", extra="peers", translatable=translatable_to_pybullet,
                     open=PyBulletWorld),
    "rapier-t1": Peer("rapier-t1", package="rapier3d", extra="peers", translatable=translatable_to_pybullet,
                      open=lambda scene, iterations: RapierWorld(scene, iterations, threads=1)),
    "rapier-t2": Peer("rapier-t2", package="rapier3d", extra="peers", translatable=translatable_to_pybullet,
                      open=lambda scene, iterations: RapierWorld(scene, iterations, threads=2)),
}
"""Every peer engine by name. ``sandbox bench`` runs ``pybullet`` beside our solvers;
``benchmarks/peer_speed.py`` runs any of them."""
