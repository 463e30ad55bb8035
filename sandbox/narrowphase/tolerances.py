"""Numerical tolerances of the narrowphase: each with its unit, size and the reason for it.

These are geometric constants of the contact *generation* (how to tell a face
from an edge contact, when two directions count as parallel), not tunables of
the physics; the speculative ``margin`` comes from ``Settings.contact_margin``
as an argument. They are Python constants read at compile time, so changing
one needs a new process (Taichi bakes globals into kernels).
"""

NO_AXIS = -1.0e30
"""[m] Separation of "no candidate axis yet". Any real separation is larger;
code tests ``x > NO_AXIS_HALF`` to ask "was an axis found"."""

NO_AXIS_HALF = -0.5e30
"""[m] Threshold between NO_AXIS and real separations."""

SAT_FACE_B_REL_TOL = 0.02
"""[1] Face B is used as the reference face only if its separation beats face A's
by this fraction of |sep| plus SAT_ABS_TOL (Gregorius GDC 2013 / Box2D 3D use
0.98 * sep). Without a bias the reference flips between two nearly equal faces
of a resting pair from frame to frame, and every flip renames all four feature
ids, which throws away the warm-start impulses."""

SAT_EDGE_REL_TOL = 0.10
"""[1] An edge-edge axis wins over the best face axis only if its separation is
larger by this fraction of |sep| plus SAT_ABS_TOL (Gregorius: 0.90 * sep). Edge
contacts give one point, face contacts up to four, so near ties go to faces."""

SAT_ABS_TOL = 1.0e-3
"""[m] Absolute part of the two biases above. Changing features for a difference this small
gains nothing, and the resting box-on-box stability test perturbs by 1e-5 m / 1e-4 rad, about
5e-5 m of separation difference, well inside. (Written as "a fifth of the default slop" when
that was 5 mm; it is 0.5 mm, so a switch of features may deepen a contact by up to
twice the slop. On the rocking box of docs/method-notes.md "A rocking box" the biases were not
the cause: without them it rocked harder.)"""

INCIDENT_TIE_COS = 1.0e-3
"""[1] Two incident-face candidates whose normals' dot products with the
reference normal differ by less than this count as tied, and the lower face
index wins. A box balanced on an edge has two faces at exactly 45 degrees;
float noise would otherwise alternate the incident face (and the ids)."""

CORNER_MIN_COS = 1.0e-6
"""[1] A reference-face corner is projected onto the incident face along the
reference normal only if the two normals are at least this anti-parallel;
below, the projection divides by ~0 (the faces are perpendicular, and the
corner is not a contact point anyway)."""

EDGE_PARALLEL_SIN = 0.005
"""[1] Edge pairs with |e1 x e2| < this * |e1| |e2| (about 0.3 degrees) are
skipped as SAT axes: their cross product is noise, and a parallel edge pair is
always dominated by a face axis (Gregorius uses the same 0.005)."""

FRONT_MIN_COS = 1.0e-3
"""[1] One-sided triangles: a face axis of the other polytope may give the
contact normal only if pushing that polytope along it has at least this
cosine with the triangle's front normal. Zero would be the exact rule; the
small positive value stops in-plane axes (a box side face next to a floor
triangle, cosine ~1e-8 after rotation round-off) from being admitted by noise
and shoving bodies sideways."""

FACE_PREFERENCE_ABS = 1.0e-5
"""[m] Sphere/capsule vs polytope: a face axis keeps priority over an edge or
vertex axis unless the latter is larger by this much. Round-off alone makes an
edge axis of a capsule lying flat on a face win by ~1e-7 m, which would turn a
2-point manifold into a rocking 1-point one; 10 um is 100x that noise and far
below any physical scale of the sandbox."""

CAPSULE_PARALLEL_SIN = 0.05
"""[1] Capsule-capsule: segments whose directions differ by less than about
3 degrees are treated as parallel and get two points (the ends of their common
extent). A log resting on a log is never exactly parallel; one point there
would let it rock about the contact."""

LENGTH_EPS = 1.0e-6
"""[m] Below this a difference vector is too short to normalise in f32 (its
direction is round-off); callers then fall back to a deterministic direction."""

LENGTH_EPS2 = LENGTH_EPS * LENGTH_EPS
"""[m^2] Square of LENGTH_EPS, for comparisons against squared lengths."""

PARALLEL_EPS2 = 1.0e-10
"""[1] Closest points of two segments: sin^2 of the angle below which the
segments are solved as parallel (Ericson's denominator test, made relative so
it does not depend on the segment lengths)."""

REDUCE_AREA_EPS = 1.0e-10
"""[m^2] Manifold reduction: a candidate must add more than this area (1e-5 m
square) to be worth a point; below, the points are collinear or coincident and
another one carries no extra moment arm."""

REDUCE_GAP_LENGTH = 1.0e-3
"""[m] Manifold reduction: after the deepest point, a candidate's lever arm or area counts
1 / (1 + g / REDUCE_GAP_LENGTH), g its separation above the deepest point's (or above touching,
when the deepest touches). By area alone, a box tilted across another's edge kept a point 18.7 mm
up in the speculative margin and dropped the corner 0.7 mm from touching that it rocked onto; the
corner arrived 1.7-2.3 mm deep a few steps later, was pushed back out, and the box rocked for good
(0.1 m/s under every solver; docs/method-notes.md "A rocking box: the manifold's reduction").
0.25-4 mm stopped it there, 10 mm did not; 1 mm is twice the default slop. Points that all touch
keep the plain area rule: their gaps are zero."""

CLIP_EPS = 1.0e-4
"""[m] Face clipping: a point this close to a side plane (or to an incident
edge) counts as lying on it, and an edge must cross a plane by more than this
on both sides to make a crossing point. Coinciding borders (a box on an equal
box, boxes in a pyramid) then give their vertices once, with stable ids,
instead of near-duplicate crossings that flicker with round-off; 0.1 mm is
above f32 round-off of coordinates up to ~100 m and below any visible scale.
A point may lie this far outside the reference face, which is harmless."""
