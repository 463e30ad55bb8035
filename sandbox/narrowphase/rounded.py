"""Pairs of rounded shapes, and rounded shapes against planes.

A sphere is a point core and a capsule a segment core, each inflated by its
radius, so these pairs are "closest points of the cores, minus the radii".
The only subtlety is the number of points: a capsule lying on a plane or on a
parallel capsule needs two points, or it rocks about the single closest
point; those two points come from the segment ends (plane) or from clipping
one segment to the extent of the other (capsule-capsule).

Feature ids: plane-capsule uses the capsule end (0 at -z, 1 at +z);
capsule-capsule uses 0 and 1 for the two ends of the common extent and 2 for a
single closest-point contact; all other pairs have one point with id 0.
"""

import taichi as ti

from ..math3d import cross, dot, norm, plane_basis
from .manifold import Manifold, ShapePose, manifold_add
from .segments import closest_on_segment, closest_segments, core_segment
from .tolerances import CAPSULE_PARALLEL_SIN, LENGTH_EPS, LENGTH_EPS2

vec3 = ti.math.vec3


@ti.func
def _unit_or(v: vec3, fallback: vec3) -> vec3:
    """v normalised, or the fallback when v is too short to have a direction."""
    out = fallback
    n = norm(v)
    if n > LENGTH_EPS:
        out = v / n
    return out


@ti.func
def _perpendicular_towards(axis: vec3, towards: vec3) -> vec3:
    """A unit vector perpendicular to ``axis`` leaning towards ``towards``.

    Used when two cores touch (zero-length closest vector): the contact normal
    must still be perpendicular to a capsule's axis, and should push the shapes
    apart along their centre offset when that offset says anything.
    """
    a = _unit_or(axis, vec3(0.0, 0.0, 1.0))
    t1, _t2 = plane_basis(a)
    w = towards - a * dot(a, towards)
    return _unit_or(w, t1)


@ti.func
def _add_pair_point(m: ti.template(), pa: vec3, pb: vec3, n: vec3, ra: ti.f32, rb: ti.f32,
                    margin: ti.f32, feature: ti.i32):
    """Add the contact between core points pa (of a) and pb (of b) along normal n (a to b)."""
    sep = dot(pb - pa, n) - ra - rb
    if sep < margin:
        manifold_add(m, 0.5 * ((pa + ra * n) + (pb - rb * n)), sep, feature)


@ti.func
def collide_plane_sphere(a: ShapePose, b: ShapePose, margin: ti.f32) -> Manifold:
    m = Manifold(count=0, normal=a.normal)
    _add_pair_point(m, b.pos - a.normal * dot(a.normal, b.pos - a.pos), b.pos, a.normal, 0.0, b.radius, margin, 0)
    return m


@ti.func
def collide_plane_capsule(a: ShapePose, b: ShapePose, margin: ti.f32) -> Manifold:
    """Each core end within the margin is a point, so a capsule lying flat gets two."""
    m = Manifold(count=0, normal=a.normal)
    e0, e1 = core_segment(b.pos, b.rot, b.half_height)
    n = a.normal
    _add_pair_point(m, e0 - n * dot(n, e0 - a.pos), e0, n, 0.0, b.radius, margin, 0)
    _add_pair_point(m, e1 - n * dot(n, e1 - a.pos), e1, n, 0.0, b.radius, margin, 1)
    return m


@ti.func
def collide_sphere_sphere(a: ShapePose, b: ShapePose, margin: ti.f32) -> Manifold:
    # coincident centres: any direction is a valid normal; +z is deterministic
    n = _unit_or(b.pos - a.pos, vec3(0.0, 0.0, 1.0))
    m = Manifold(count=0, normal=n)
    _add_pair_point(m, a.pos, b.pos, n, a.radius, b.radius, margin, 0)
    return m


@ti.func
def collide_sphere_capsule(a: ShapePose, b: ShapePose, margin: ti.f32) -> Manifold:
    b0, b1 = core_segment(b.pos, b.rot, b.half_height)
    q = closest_on_segment(a.pos, b0, b1)
    fallback = _perpendicular_towards(b1 - b0, b.pos - a.pos)
    n = _unit_or(q - a.pos, fallback)
    m = Manifold(count=0, normal=n)
    _add_pair_point(m, a.pos, q, n, a.radius, b.radius, margin, 0)
    return m


@ti.func
def collide_capsule_capsule(a: ShapePose, b: ShapePose, margin: ti.f32) -> Manifold:
    """Closest points of the segments; two points when they are parallel and overlap.

    The normal comes from the segment closest points (not from the cross
    product of the axes): for nearly parallel, coplanar segments the cross
    product is perpendicular to the plane they share, which is the wrong way.
    """
    a0, a1 = core_segment(a.pos, a.rot, a.half_height)
    b0, b1 = core_segment(b.pos, b.rot, b.half_height)
    ca, cb = closest_segments(a0, a1, b0, b1)
    da = a1 - a0
    db = b1 - b0
    # touching cores: perpendicular to both axes (or to a's) towards b
    axes_normal = cross(da, db)
    if dot(axes_normal, b.pos - a.pos) < 0.0:
        axes_normal = -axes_normal
    fallback = _unit_or(axes_normal, _perpendicular_towards(da, b.pos - a.pos))
    n = _unit_or(cb - ca, fallback)
    m = Manifold(count=0, normal=n)

    la2 = dot(da, da)
    lb2 = dot(db, db)
    cross2 = dot(axes_normal, axes_normal)
    parallel = (la2 > LENGTH_EPS2 and lb2 > LENGTH_EPS2
                and cross2 < CAPSULE_PARALLEL_SIN * CAPSULE_PARALLEL_SIN * la2 * lb2)
    if parallel:
        # clip b's extent to a's: parameters of b's ends along a, intersected with [0, 1]
        t0 = dot(b0 - a0, da) / la2
        t1 = dot(b1 - a0, da) / la2
        lo = ti.max(0.0, ti.min(t0, t1))
        hi = ti.min(1.0, ti.max(t0, t1))
        if (hi - lo) * ti.sqrt(la2) > LENGTH_EPS:
            pa_lo = a0 + lo * da
            pa_hi = a0 + hi * da
            _add_pair_point(m, pa_lo, closest_on_segment(pa_lo, b0, b1), n, a.radius, b.radius, margin, 0)
            _add_pair_point(m, pa_hi, closest_on_segment(pa_hi, b0, b1), n, a.radius, b.radius, margin, 1)
        else:
            parallel = False
    if not parallel:
        _add_pair_point(m, ca, cb, n, a.radius, b.radius, margin, 2)
    return m
