"""Closed triangle meshes for non-convex bodies: generators, files, and the checks CoACD needs.

A non-convex body starts as a closed, outward-wound triangle mesh, either read
from a file with trimesh (OBJ, STL, PLY, OFF, GLB ... ``force="mesh"``) or made
by one of the generators below. ``decompose.py`` then cuts it into convex hulls.

CoACD has no input checks of its own (docs/apis.md section 2): an empty mesh or
a NaN vertex aborts the interpreter, and an open mesh is voxel-remeshed into a
thin shell of 10^5 triangles that runs for minutes. ``checked_mesh`` is
therefore strict. It repairs only what cannot change the solid: duplicate
vertices are merged and zero-area triangles dropped (trimesh's ``process``; an
STL triangle soup becomes a connected mesh this way), and an
inside-out mesh (negative volume) is inverted. Everything else is an error
(``MeshError``, which the loader turns into a SceneError naming the file and
entry): no triangles, NaN or inf, indices out of range, open edges (holes are
not filled: a guessed patch would change the mass), zero volume, more than
``MAX_MESH_FACES`` triangles.

Generators (all watertight, outward wound, in the body's shape frame, lengths in m):

* ``torus``: major radius R in the xy plane around z, tube radius r;
  ``sections = [around, tube]``.
* ``l_block``: an L in the xy plane (bounding box ``size`` x by y, both arms
  ``arm`` wide), extruded along z by ``size[2]``; the bounding box is centred.
* ``window_wall``: a wall of ``size = [width x, thickness y, height z]`` with a
  rectangular ``window = [width, height]`` through it along y, centred at
  ``window_center = [x, z]`` (default the wall's centre); bounding box centred.
* ``bowl``: a hemispherical shell of outer ``radius`` and ``thickness``, open
  towards +z, rim at z = 0 (the sphere's centre), bottom at z = -radius;
  ``sections = [around, along the profile]``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

MAX_MESH_FACES = 200_000
"""Largest mesh decomposed: CoACD's time grows with the triangle count (a 2304-triangle
torus takes ~10 s at threshold 0.05 on one core), and a bigger mesh is better simplified
in a modeller first."""

GENERATORS = ("torus", "l_block", "window_wall", "bowl")
GENERATOR_KEYS = {  # kind -> {key: default}; the loader validates types and ranges
    "torus": {"major_radius": 0.5, "minor_radius": 0.15, "sections": (24, 12)},
    "l_block": {"size": (1.0, 1.0, 0.4), "arm": 0.4},
    "window_wall": {"size": (2.0, 0.2, 1.5), "window": (0.8, 0.6), "window_center": None},
    "bowl": {"radius": 0.5, "thickness": 0.06, "sections": (16, 6)},
}
MAX_SECTIONS = 256
"""Per generator axis; more only makes CoACD slower."""


class MeshError(ValueError):
    """A mesh cannot be used (the loader re-raises it as a SceneError with its entry)."""


# ---------------------------------------------------------------------------- generators
def torus(major_radius: float, minor_radius: float, sections=(24, 12)) -> tuple[np.ndarray, np.ndarray]:
    import trimesh

    if not 0 < minor_radius < major_radius:
        raise MeshError(f"a torus needs 0 < minor_radius < major_radius, got {minor_radius} and {major_radius}")
    m = trimesh.creation.torus(major_radius, minor_radius, major_sections=int(sections[0]),
                               minor_sections=int(sections[1]))
    return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int64)


def l_block(size=(1.0, 1.0, 0.4), arm: float = 0.4) -> tuple[np.ndarray, np.ndarray]:
    x, y, z = (float(s) for s in size)
    if not (0 < arm < x and arm < y):
        raise MeshError(f"an L-block needs 0 < arm < size x and size y, got arm {arm} and size {[x, y, z]}")
    outline = [(0, 0), (x, 0), (x, arm), (arm, arm), (arm, y), (0, y)]
    return _extrude(outline, [], z, offset=(-x / 2, -y / 2, -z / 2))


def window_wall(size=(2.0, 0.2, 1.5), window=(0.8, 0.6), window_center=None) -> tuple[np.ndarray, np.ndarray]:
    w, t, h = (float(s) for s in size)
    ww, wh = (float(s) for s in window)
    cx, cz = (w / 2, h / 2) if window_center is None else (float(window_center[0]) + w / 2,
                                                            float(window_center[1]) + h / 2)
    lo_x, hi_x, lo_z, hi_z = cx - ww / 2, cx + ww / 2, cz - wh / 2, cz + wh / 2
    if not (0 < lo_x and hi_x < w and 0 < lo_z and hi_z < h):
        raise MeshError(f"the window {[ww, wh]} at {[cx - w / 2, cz - h / 2]} does not fit inside the wall "
                        f"{[w, h]} with a frame on every side")
    hole = [(lo_x, lo_z), (hi_x, lo_z), (hi_x, hi_z), (lo_x, hi_z)]
    v, f = _extrude([(0, 0), (w, 0), (w, h), (0, h)], [hole], t, offset=(-w / 2, -h / 2, -t / 2))
    # the polygon lives in x-z: extruded along +z, then turned so the extrusion runs along y
    v = v[:, [0, 2, 1]]
    return v, f[:, ::-1].copy()  # swapping two axes mirrors the mesh: flip the winding back


def bowl(radius: float = 0.5, thickness: float = 0.06, sections=(16, 6)) -> tuple[np.ndarray, np.ndarray]:
    import trimesh

    if not 0 < thickness < radius:
        raise MeshError(f"a bowl needs 0 < thickness < radius, got {thickness} and {radius}")
    n = int(sections[1]) + 1
    th = np.linspace(0.0, np.pi / 2, n)
    outer = np.c_[radius * np.sin(th), -radius * np.cos(th)]
    inner = np.c_[(radius - thickness) * np.sin(th), -(radius - thickness) * np.cos(th)][::-1]
    profile = np.vstack([outer, inner])  # (r, z): bottom centre, out and up the outside, down the inside
    m = trimesh.creation.revolve(profile, sections=int(sections[0]))
    return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int64)


def _extrude(outline, holes, height: float, offset) -> tuple[np.ndarray, np.ndarray]:
    import trimesh

    try:
        import manifold3d  # noqa: F401  (trimesh's polygon triangulation engine)
        import shapely
    except ImportError as exc:
        raise MeshError(f"this generator needs {exc.name}: pip install {exc.name} (a dependency of mass-splitting-sandbox)") from None

    m = trimesh.creation.extrude_polygon(shapely.Polygon(outline, holes), float(height))
    return np.asarray(m.vertices, dtype=np.float64) + np.asarray(offset, dtype=np.float64), np.asarray(m.faces,
                                                                                                        np.int64)


def generate(kind: str, params: dict) -> tuple[np.ndarray, np.ndarray]:
    """The mesh of generator ``kind`` with ``params`` (defaults filled in from GENERATOR_KEYS)."""
    values = dict(GENERATOR_KEYS[kind])
    values.update(params)
    return {"torus": torus, "l_block": l_block, "window_wall": window_wall, "bowl": bowl}[kind](**values)


# ---------------------------------------------------------------------------- files and checks
def read_mesh_file(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) of a mesh file as written, every trimesh failure turned into a
    MeshError. Unprocessed: trimesh's processing silently drops NaN vertices and their
    triangles, which would turn a damaged file into a merely open one; the callers check the
    arrays first (``checked_mesh``, mesh_reader.load_mesh_file), then process them."""
    try:
        import trimesh

        mesh = trimesh.load(str(path), force="mesh", process=False)
        vertices = np.asarray(getattr(mesh, "vertices", np.empty((0, 3))), dtype=np.float64)
        faces = np.asarray(getattr(mesh, "faces", np.empty((0, 3))), dtype=np.int64)
    except IndexError as exc:  # trimesh's readers index the vertex array with the file's triangles
        raise MeshError(f"mesh file {path} has triangle indices out of range ({exc})") from None
    except Exception as exc:  # noqa: BLE001 -- any failure inside trimesh's readers is a bad file
        detail = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        raise MeshError(f"cannot read mesh file {path}: {type(exc).__name__}{': ' + detail if detail else ''}") from None
    return vertices, faces


def checked_mesh(vertices, faces, *, what: str = "mesh"):
    """A trimesh.Trimesh that CoACD can take safely, or a MeshError saying why not (module docstring)."""
    import trimesh

    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces)
    if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0 or v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
        raise MeshError(f"{what} has no triangles (vertices {v.shape}, faces {f.shape})")
    if not np.all(np.isfinite(v)):
        raise MeshError(f"{what} has NaN or inf vertex coordinates")
    if f.dtype.kind not in "iu" or f.min() < 0 or f.max() >= len(v):
        raise MeshError(f"{what} has triangle indices out of range (0..{len(v) - 1})")
    if len(f) > MAX_MESH_FACES:
        raise MeshError(f"{what} has {len(f)} triangles; at most {MAX_MESH_FACES} are decomposed "
                        "(MAX_MESH_FACES): simplify it first")
    size = float(np.ptp(v, axis=0).max())
    if not size > 0:
        raise MeshError(f"{what} is degenerate: all vertices coincide")
    with np.errstate(all="ignore"):
        mesh = trimesh.Trimesh(v, f.astype(np.int64), process=True)  # merge vertices, drop degenerate faces
        if len(mesh.faces) == 0:
            raise MeshError(f"{what} is degenerate: every triangle has zero area")
        if not mesh.is_watertight:
            open_edges = int(np.sum(np.bincount(mesh.edges_unique_inverse, minlength=len(mesh.edges_unique)) != 2))
            raise MeshError(f"{what} is not watertight ({open_edges} edges do not have exactly two triangles); "
                            "close its holes in a modeller: CoACD would voxel-remesh it into a thin shell")
        if mesh.volume < 0:
            mesh.invert()  # inside-out: the same solid, wound the other way
        if not (mesh.is_volume and mesh.volume > 1e-9 * size**3):
            raise MeshError(f"{what} encloses no volume (volume {mesh.volume:.3g} m^3 for a {size:.3g} m extent): "
                            "it is flat, or its triangles are wound inconsistently")
    return mesh
