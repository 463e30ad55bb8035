"""Narrowphase: the contact manifold of one shape pair, dispatched on the kind pair.

``collide(pool, a, b, margin)`` returns a ``Manifold`` (see ``manifold.py``):
normal from a to b, at most four points midway between the surfaces, each
with its signed separation and a feature id; only points closer than
``margin`` (speculative contacts) are reported.

Dispatch follows Box2D's ``contact.c``: kinds are ordered plane < sphere <
capsule < box < hull < triangle and there is one routine per unordered pair,
written for the lower kind first. When ``a.kind > b.kind`` the routine runs
with the shapes swapped and the normal is flipped back; points, separations
and feature ids do not depend on the order. Families, one module each:

* ``rounded``: plane-sphere, plane-capsule, sphere-sphere, sphere-capsule,
  capsule-capsule (closest points of point/segment cores);
* ``core_polytope``: sphere or capsule against box/hull/triangle (exact
  signed distance of the core; one routine, a sphere is a zero-length core);
* ``polytope``: plane-polytope (vertices, reduced to four) and
  polytope-polytope (SAT in ``sat``, face clipping in ``clip``, reduction in
  ``reduce``). Box, hull and triangle share the polytope pool and the code.

Mesh triangles are static and one-sided (front = face 0): see ``polytope``.
Plane-plane, plane-triangle and triangle-triangle never meet and return no
points.

``collide_kinds`` is the same dispatcher with a static tuple of the kinds a
scene contains: routines for absent kinds are not compiled (house rule 8), a
pile of boxes does not pay compile time for capsules and meshes.
"""

import taichi as ti

from ..math3d import norm
from ..shapes import BOX, CAPSULE, HULL, PLANE, SPHERE, TRIANGLE
from .core_polytope import collide_core_polytope
from .manifold import MAX_POINTS, Manifold, ShapePose, manifold_add, manifold_point
from .polytope import collide_plane_polytope, collide_polytope_polytope
from .rounded import (collide_capsule_capsule, collide_plane_capsule, collide_plane_sphere,
                      collide_sphere_capsule, collide_sphere_sphere)

vec3 = ti.math.vec3

ALL_KINDS = (PLANE, SPHERE, CAPSULE, BOX, HULL, TRIANGLE)

# A sphere is a capsule with a zero-length core: one routine serves both pairs.
collide_sphere_polytope = collide_core_polytope
collide_capsule_polytope = collide_core_polytope

__all__ = [
    "ALL_KINDS", "MAX_POINTS", "Manifold", "ShapePose", "collide", "collide_kinds",
    "collide_plane_sphere", "collide_plane_capsule", "collide_plane_polytope",
    "collide_sphere_sphere", "collide_sphere_capsule", "collide_capsule_capsule",
    "collide_sphere_polytope", "collide_capsule_polytope", "collide_core_polytope",
    "collide_polytope_polytope", "manifold_add", "manifold_point",
]


def _has(kinds, *wanted) -> bool:
    return all(k in kinds for k in wanted)


def _has_any(kinds, *wanted) -> bool:
    return any(k in kinds for k in wanted)


@ti.func
def collide_kinds(pool: ti.template(), a: ShapePose, b: ShapePose, margin: ti.f32, kinds: ti.template()) -> Manifold:
    """``collide`` compiled only for the kinds in the static tuple ``kinds``."""
    lo = a
    hi = b
    swap = a.kind > b.kind
    if swap:
        lo = b
        hi = a
    m = Manifold(count=0, normal=vec3(0.0, 0.0, 1.0))
    # bounding spheres (bound 0 = not given, planes have inf) cull far pairs before any routine
    near = True
    if a.bound > 0.0 and b.bound > 0.0:
        m.gap = norm(a.pos - b.pos) - a.bound - b.bound
        near = m.gap < margin
    if near:
        ka = lo.kind
        kb = hi.kind
        poly_b = kb == BOX or kb == HULL or kb == TRIANGLE
        if ti.static(_has(kinds, PLANE, SPHERE)):
            if ka == PLANE and kb == SPHERE:
                m = collide_plane_sphere(lo, hi, margin)
        if ti.static(_has(kinds, PLANE, CAPSULE)):
            if ka == PLANE and kb == CAPSULE:
                m = collide_plane_capsule(lo, hi, margin)
        if ti.static(_has(kinds, PLANE) and _has_any(kinds, BOX, HULL)):
            if ka == PLANE and (kb == BOX or kb == HULL):
                m = collide_plane_polytope(pool, lo, hi, margin)
        if ti.static(_has(kinds, SPHERE)):
            if ka == SPHERE and kb == SPHERE:
                m = collide_sphere_sphere(lo, hi, margin)
        if ti.static(_has(kinds, SPHERE, CAPSULE)):
            if ka == SPHERE and kb == CAPSULE:
                m = collide_sphere_capsule(lo, hi, margin)
        if ti.static(_has(kinds, CAPSULE)):
            if ka == CAPSULE and kb == CAPSULE:
                m = collide_capsule_capsule(lo, hi, margin)
        if ti.static(_has_any(kinds, SPHERE, CAPSULE) and _has_any(kinds, BOX, HULL, TRIANGLE)):
            if (ka == SPHERE or ka == CAPSULE) and poly_b:
                m = collide_core_polytope(pool, lo, hi, margin)
        if ti.static(_has_any(kinds, BOX, HULL)):
            if (ka == BOX or ka == HULL) and poly_b:
                m = collide_polytope_polytope(pool, lo, hi, margin, kinds)
    if swap:
        m.normal = -m.normal
        m.normal_on_b = 1 - m.normal_on_b  # a routine's B is our A
    return m


@ti.func
def collide(pool: ti.template(), a: ShapePose, b: ShapePose, margin: ti.f32) -> Manifold:
    """Contact manifold between shapes a and b (normal from a to b), all kind pairs compiled."""
    return collide_kinds(pool, a, b, margin, ALL_KINDS)
