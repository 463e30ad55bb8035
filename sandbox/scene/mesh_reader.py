"""Readers of everything made of triangles: mesh files, ``shape = "mesh"`` bodies (decomposed into
convex hulls by CoACD, ``decompose.py``), static planes, static meshes and height fields.

A mesh file is read once per load (``Context.cache``), whichever entries name it.
"""

from __future__ import annotations

import numpy as np

from . import decompose, meshes, terrain
from .hull import MAX_HULL_VERTICES, HullError, reduce_to_hull
from .keys import (DECOMPOSITION_KEYS, DEFAULT_FRICTION, DEFAULT_RESTITUTION, HEIGHTFIELD_KEYS, HEIGHTFIELD_REQUIRED,
                   MAX_HEIGHTFIELD_CELLS, MAX_SEED, MESH_KEYS, PLANE_KEYS)
from .rotations import quat_to_matrix
from .schema import Reader
from .spec import MeshSpec, PlaneSpec, ShapeSpec


def load_mesh_file(r: Reader, key: str, process: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) of a mesh file read with trimesh (force='mesh'), cached per load; with
    ``process``, vertices merged and degenerate triangles dropped, after the checks: trimesh's
    own processing would drop NaN vertices and their triangles without a word."""
    path = r.file(key)
    cached = r.ctx.cache.get((path.resolve(), process))
    if cached is not None:
        return cached
    try:
        vertices, faces = meshes.read_mesh_file(path)
    except meshes.MeshError as exc:
        raise r.error(str(exc), key) from None
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0 or vertices.ndim != 2 or vertices.shape[1] != 3:
        raise r.error(f"mesh file {path} contains no triangles", key)
    if not np.all(np.isfinite(vertices)):
        raise r.error(f"mesh file {path} has NaN or inf vertex coordinates", key)
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise r.error(f"mesh file {path} has triangle indices out of range", key)
    if process:
        import trimesh

        processed = trimesh.Trimesh(vertices, faces, process=True)
        vertices = np.asarray(processed.vertices, dtype=np.float64)
        faces = np.asarray(processed.faces, dtype=np.int64)
    r.ctx.cache[(path.resolve(), process)] = (vertices, faces)
    return vertices, faces



def read_mesh_body(r: Reader) -> tuple[list[ShapeSpec], "decompose.Decomposition | None"]:
    """A ``shape = "mesh"`` body: its hulls and their decomposition (None when it fell back to one hull)."""
    source = r.exclusive("path", "generator")
    scale = r.scalar_or_vector("scale", 3, 1.0, positive=True)
    if source == "path":
        vertices, faces = load_mesh_file(r, "path", process=False)  # checked_mesh processes it
        what = f"mesh file {r.file('path')}"
    else:
        vertices, faces = _read_mesh_generator(r.table("generator"))
        what = "the generated mesh"
    options, on_failure = _read_decomposition(r.table("decomposition", None))
    vertices = vertices * scale
    if not np.all(np.isfinite(vertices)):
        raise r.error("mesh vertices overflow to inf after scale", "scale")
    try:
        mesh = meshes.checked_mesh(vertices, faces, what=what)
    except meshes.MeshError as exc:
        raise r.error(str(exc), source) from None
    try:
        result = decompose.decompose(mesh, options)
    except decompose.DecompositionError as exc:
        if on_failure == "error":
            raise r.error(f"convex decomposition of {what} failed: {exc} (with decomposition.on_failure = \"hull\" "
                          "the body is kept whole as its convex hull instead)", source) from None
        try:
            hull = reduce_to_hull(mesh.vertices)
        except HullError as hull_exc:
            raise r.error(f"convex decomposition of {what} failed ({exc}), and so did its convex hull ({hull_exc})",
                          source) from None
        r.ctx.warnings.append(f"{r.entry}: convex decomposition of {what} failed ({exc}); the body is kept whole as "
                              "the convex hull of its mesh")
        return [ShapeSpec("hull", vertices=hull)], None
    for note in result.notes:
        r.ctx.warnings.append(f"{r.entry}: {note}")
    if result.covered < 0.99:
        why = (f"{result.repaired_pairs} overlapping hull pair(s) were cut apart" if result.repaired_pairs
               else "CoACD's hulls miss part of it")
        r.ctx.warnings.append(f"{r.entry}: the hulls hold {result.covered:.1%} of {what}'s volume ({why}); its "
                              "density was scaled so that the mass is still density x the mesh's volume")
    return [ShapeSpec("hull", vertices=h) for h in result.hulls], result


def _read_mesh_generator(r: Reader) -> tuple[np.ndarray, np.ndarray]:
    kind = r.string("kind", choices=meshes.GENERATORS, what="mesh generator")
    keys = meshes.GENERATOR_KEYS[kind]
    r.check_keys(("kind",) + tuple(keys), required=("kind",), what=f"a '{kind}' mesh generator")
    params = {}
    for key, default in keys.items():
        if not r.has(key):
            continue
        if key == "sections":
            params[key] = tuple(int(n) for n in r.int_vector(key, 2, minimum=3, maximum=meshes.MAX_SECTIONS))
        elif key in ("size",):
            params[key] = r.vector(key, 3, positive=True)
        elif key in ("window",):
            params[key] = r.vector(key, 2, positive=True)
        elif key == "window_center":
            params[key] = r.vector(key, 2)
        else:
            params[key] = r.real(key, positive=True)
    try:
        return meshes.generate(kind, params)
    except meshes.MeshError as exc:
        raise r.error(str(exc)) from None


def _read_decomposition(r: Reader | None) -> tuple["decompose.DecomposeOptions", str]:
    if r is None:
        return decompose.DecomposeOptions(), "error"
    r.check_keys(DECOMPOSITION_KEYS, what="decomposition")
    options = decompose.DecomposeOptions(
        threshold=r.real("threshold", decompose.DEFAULT_THRESHOLD, low=0.01, high=1.0),
        max_hulls=r.integer("max_hulls", None, minimum=1, maximum=4096),
        seed=r.integer("seed", 0, minimum=0, maximum=MAX_SEED),
        max_hull_vertices=r.integer("max_hull_vertices", MAX_HULL_VERTICES, minimum=4, maximum=MAX_HULL_VERTICES),
        timeout=r.real("timeout", decompose.DEFAULT_TIMEOUT, positive=True),
    )
    return options, r.string("on_failure", "error", choices=("error", "hull"), what="on_failure choice")


# ---------------------------------------------------------------------------- static planes and meshes
def read_plane(r: Reader) -> PlaneSpec:
    r.check_keys(PLANE_KEYS, required=("normal",), what="a static plane")
    normal = r.vector("normal", 3, nonzero=True)
    return PlaneSpec(
        normal=normal / np.linalg.norm(normal),
        offset=r.real("offset", 0.0),
        friction=r.real("friction", DEFAULT_FRICTION, nonnegative=True),
        restitution=r.real("restitution", DEFAULT_RESTITUTION, low=0.0, high=1.0),
    )


def _read_heightfield(r: Reader) -> tuple[np.ndarray, np.ndarray]:
    function = r.string("function", choices=terrain.FUNCTIONS, what="height-field function")
    r.check_keys(HEIGHTFIELD_KEYS[function], required=HEIGHTFIELD_REQUIRED[function], what=f"a '{function}' height field")
    size = r.vector("size", 2, positive=True)
    cells = r.int_vector("cells", 2, minimum=1, maximum=MAX_HEIGHTFIELD_CELLS)
    amplitude = r.real("amplitude", nonnegative=True)
    if function == "sines":
        vertices, triangles = terrain.heightfield("sines", size=size, cells=cells, amplitude=amplitude,
                                                  frequency=r.scalar_or_vector("frequency", 2, 1.0))
    else:
        vertices, triangles = terrain.heightfield("noise", size=size, cells=cells, amplitude=amplitude,
                                                  seed=r.integer("seed", minimum=0),
                                                  smoothing=r.integer("smoothing", 2, minimum=0, maximum=64))
    if not np.all(np.isfinite(vertices)):
        raise r.error("height-field vertices are not finite; check size, amplitude and frequency")
    return vertices, triangles


def read_mesh(r: Reader) -> MeshSpec:
    r.check_keys(MESH_KEYS, what="a static mesh")
    source = r.exclusive("path", "heightfield")
    position = r.vector("position", 3, (0.0, 0.0, 0.0))
    orientation = r.quaternion("orientation")
    scale = r.scalar_or_vector("scale", 3, 1.0, positive=True)
    if source == "path":
        vertices, triangles = load_mesh_file(r, "path")
    else:
        vertices, triangles = _read_heightfield(r.table("heightfield"))
    with np.errstate(all="ignore"):
        vertices = (vertices * scale) @ quat_to_matrix(orientation).T + position
    if not np.all(np.isfinite(vertices)):
        raise r.error("mesh vertices overflow to inf after scale and position")
    name = r.string("name", None)
    if name is not None and not name:
        raise r.error("a name must not be empty", "name")
    return MeshSpec(
        vertices=vertices,
        triangles=np.ascontiguousarray(triangles, dtype=np.int64),
        friction=r.real("friction", DEFAULT_FRICTION, nonnegative=True),
        restitution=r.real("restitution", DEFAULT_RESTITUTION, low=0.0, high=1.0),
        name=name,
    )

