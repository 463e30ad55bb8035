"""What the narrowphase hands to the rest of the pipeline: a shape's world pose in,
a contact manifold of at most four points out.

Conventions, stated once: the manifold normal points from shape A to shape B;
``separation`` is the signed distance along the normal (> 0 gap, < 0
penetration); ``points`` lie midway between the two surfaces; a feature id is
an integer that stays the same from frame to frame while the same pair of
geometric features (face/edge/vertex) produces the point, so the persistence
stage can carry impulses over (warm starting).
"""


import taichi as ti

from ..math3d import quat_conj, quat_mul, quat_rotate_inv

vec3 = ti.math.vec3
vec4 = ti.math.vec4
MAX_POINTS = 4


@ti.dataclass
class ShapePose:
    """One shape placed in the world, as the narrowphase needs it."""

    kind: ti.i32  # shapes.PLANE ... shapes.TRIANGLE
    pos: vec3  # world position of the shape origin (plane: any point on it)
    rot: vec4  # world orientation (w, x, y, z); planes: unused
    normal: vec3  # planes only: unit outward normal (the solid is n.x <= n.pos)
    radius: ti.f32  # sphere / capsule radius [m]
    half_height: ti.f32  # capsule: half length of the core segment along local z [m]
    poly: ti.i32  # box / hull / triangle: polytope id in the PolytopePool
    bound: ti.f32  # radius of a sphere about pos enclosing the shape [m] (inf for planes)


@ti.func
def relative_pose(a: ShapePose, b: ShapePose):
    """(position, orientation) of shape b in shape a's frame."""
    return quat_rotate_inv(a.rot, b.pos - a.pos), quat_mul(quat_conj(a.rot), b.rot)


@ti.dataclass
class Manifold:
    count: ti.i32
    normal: vec3  # from A to B, unit
    points: ti.types.matrix(MAX_POINTS, 3, ti.f32)  # row k = world point k
    separation: vec4
    feature: ti.types.vector(MAX_POINTS, ti.i32)
    gap: ti.f32  # no points: a lower bound of the distance between the shapes [m] (0: none known)
    normal_on_b: ti.i32  # 1: the normal is a face normal of shape B (it turns with B), 0: of A or neither


@ti.func
def manifold_add(m: ti.template(), p: vec3, sep: ti.f32, feature: ti.i32):
    """Append one point if there is room (callers reduce to 4 before adding more)."""
    if m.count < MAX_POINTS:
        k = m.count
        for c in ti.static(range(3)):
            m.points[k, c] = p[c]
        m.separation[k] = sep
        m.feature[k] = feature
        m.count += 1


@ti.func
def manifold_point(m: ti.template(), k: ti.i32) -> vec3:
    return vec3(m.points[k, 0], m.points[k, 1], m.points[k, 2])
