"""Mass, centre of mass and inertia of the scene's shapes and bodies (uniform density).

Closed forms for box, sphere and capsule; trimesh's exact surface integrals for
hulls; compounds sum their parts with the parallel-axis theorem. All tensors are
about the centre of mass, in the frame named by the function (shape frame for a
single shape, body frame for a body). Units: density [kg/m^3], mass [kg],
lengths [m], inertia [kg m^2].

Capsule (radius r, core half length h along local z): a cylinder of length 2h
plus two hemispheres. With m_c = rho pi r^2 2h and m_s = rho 4/3 pi r^3 (both
caps together):

    I_zz = m_c r^2 / 2 + m_s 2 r^2 / 5
    I_xx = I_yy = m_c (r^2 / 4 + h^2 / 3) + m_s (2 r^2 / 5 + h^2 + 3 h r / 4)

The cap term: a hemisphere's centroid sits 3r/8 from its flat face, its inertia
about a transverse axis through the flat face is 2/5 m r^2; moving that to its
centroid and then to the capsule centre (distance h + 3r/8) gives
2/5 r^2 - (3r/8)^2 + (h + 3r/8)^2 = 2/5 r^2 + h^2 + 3hr/4 per unit mass.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .rotations import quat_to_matrix
from .spec import ShapeSpec


@dataclass
class MassProperties:
    mass: float  # [kg]
    com: np.ndarray  # (3,) [m], in the frame the tensor is expressed in
    inertia: np.ndarray  # (3, 3) about com [kg m^2]

    def scaled(self, factor: float) -> "MassProperties":
        """The same shape at ``factor`` times the density."""
        return MassProperties(self.mass * factor, self.com.copy(), self.inertia * factor)


def box_mass_properties(half_extents, density: float) -> MassProperties:
    h = np.asarray(half_extents, dtype=np.float64)
    m = density * 8.0 * h[0] * h[1] * h[2]
    hh = h * h
    inertia = np.diag([hh[1] + hh[2], hh[0] + hh[2], hh[0] + hh[1]]) * (m / 3.0)
    return MassProperties(float(m), np.zeros(3), inertia)


def box_mass_properties_batch(half_extents: np.ndarray, density) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised boxes: half_extents (N, 3), density scalar or (N,) -> masses (N,), inertia (N, 3, 3)."""
    h = np.asarray(half_extents, dtype=np.float64)
    m = np.asarray(density, dtype=np.float64) * 8.0 * h[:, 0] * h[:, 1] * h[:, 2]
    hh = h * h
    diag = np.stack([hh[:, 1] + hh[:, 2], hh[:, 0] + hh[:, 2], hh[:, 0] + hh[:, 1]], axis=1) * (m / 3.0)[:, None]
    inertia = np.zeros((len(h), 3, 3))
    inertia[:, [0, 1, 2], [0, 1, 2]] = diag
    return m, inertia


def sphere_mass_properties(radius: float, density: float) -> MassProperties:
    radius = np.float64(radius)  # numpy overflows to inf (checked by the loader); Python's ** would raise
    m = density * 4.0 / 3.0 * np.pi * radius**3
    return MassProperties(float(m), np.zeros(3), np.eye(3) * (0.4 * m * radius**2))


def capsule_mass_properties(radius: float, half_height: float, density: float) -> MassProperties:
    r, h = np.float64(radius), np.float64(half_height)
    m_c = density * np.pi * r * r * 2.0 * h
    m_s = density * 4.0 / 3.0 * np.pi * r**3
    i_zz = m_c * r * r / 2.0 + m_s * 0.4 * r * r
    i_xx = m_c * (r * r / 4.0 + h * h / 3.0) + m_s * (0.4 * r * r + h * h + 0.75 * h * r)
    return MassProperties(float(m_c + m_s), np.zeros(3), np.diag([i_xx, i_xx, i_zz]))


def hull_mass_properties(vertices, density: float) -> MassProperties:
    """Convex hull of ``vertices`` as a solid (trimesh's exact integrals), in the vertices' frame."""
    import trimesh

    mesh = trimesh.convex.convex_hull(np.asarray(vertices, dtype=np.float64))
    mesh.density = float(density)
    mp = mesh.mass_properties
    return MassProperties(float(mp.mass), np.asarray(mp.center_mass, dtype=np.float64), np.asarray(mp.inertia, dtype=np.float64))


def shape_mass_properties(shape: ShapeSpec, density: float) -> MassProperties:
    """Mass properties of one shape in its own shape frame (local pose not applied)."""
    if shape.kind == "box":
        return box_mass_properties(shape.half_extents, density)
    if shape.kind == "sphere":
        return sphere_mass_properties(shape.radius, density)
    if shape.kind == "capsule":
        return capsule_mass_properties(shape.radius, shape.half_height, density)
    if shape.kind == "hull":
        return hull_mass_properties(shape.vertices, density)
    raise ValueError(f"no mass properties for shape kind {shape.kind!r}")


def transformed(mp: MassProperties, position, orientation) -> MassProperties:
    """Express ``mp`` in a parent frame where the shape frame sits at ``position`` / ``orientation``."""
    rot = quat_to_matrix(orientation)
    return MassProperties(mp.mass, rot @ mp.com + np.asarray(position, dtype=np.float64), rot @ mp.inertia @ rot.T)


def combine(parts: list[MassProperties]) -> MassProperties:
    """Sum of parts already expressed in one common frame (parallel-axis theorem)."""
    mass = sum(p.mass for p in parts)
    com = sum(p.mass * p.com for p in parts) / mass
    inertia = np.zeros((3, 3))
    for p in parts:
        d = p.com - com
        inertia += p.inertia + p.mass * (np.dot(d, d) * np.eye(3) - np.outer(d, d))
    return MassProperties(float(mass), com, inertia)


def part_mass_properties(shapes: list[ShapeSpec], densities) -> list[MassProperties]:
    """Mass properties of each shape placed at its local pose, in the body frame.

    ``densities`` is one density for all shapes or one per shape.
    """
    if np.ndim(densities) == 0:
        densities = [float(densities)] * len(shapes)
    return [transformed(shape_mass_properties(s, d), s.local_position, s.local_orientation)
            for s, d in zip(shapes, densities)]


def body_mass_properties(shapes: list[ShapeSpec], densities) -> MassProperties:
    """Mass properties of shapes placed at their local poses in one body frame (the sum of the parts)."""
    parts = part_mass_properties(shapes, densities)
    if len(parts) == 1:
        return parts[0]
    return combine(parts)
