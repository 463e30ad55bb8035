"""Scene loading: a TOML file or a dict -> a validated, fully expanded ``Scene``.

The schema (every key, its type, unit, default and range) is documented for
users in ``scenes/README.md``; this module is its executable form. Validation is
strict: an unknown key, a wrong type, a missing required key, a non-positive
size, mass, density or dt, NaN or inf, an unreadable mesh file, a degenerate
hull, an unknown shape / solver / generator / event kind / effect, a duplicate name
or a timeline event that refers to a body that does not exist at its time raises one
``SceneError`` naming the source, the entry (``body[3].half_extents``) and the
problem. Nothing is silently defaulted or clamped; defaults exist only for keys
that are documented as optional.

Order of ``Scene.bodies``: the ``[[body]]`` entries in file order, then the
expansion of each ``[[generate]]`` entry in order, then the convex bodies of
``[[static]]`` entries in order (so body indices of a scene without static
convex bodies match the anchors' ``scenes.json`` listing). Timeline ``drop``
events append their bodies after these when they apply (``timeline.py``).

Non-convex bodies (``shape = "mesh"`` in ``[[body]]``): a mesh file or a generated
mesh (``meshes.py``), checked, then decomposed into convex hulls by CoACD in a child
process, cached on disk (``decompose.py``). The body is a compound of those hulls;
its mass is density x the mesh's volume, its centre of mass and inertia those of
the mesh's material (each hull carries the part of the mesh inside it, which is
also what it weighs when the body fractures).

Centre of mass: a body's ``position`` in the file is the origin of its shape
frame (the frame its hull vertices or compound parts are written in). The
loader computes the centre of mass c in that frame, moves every shape by -c
(``ShapeSpec.local_position``) and stores position + R c in ``BodySpec.position``,
which is therefore the centre of mass. Box, sphere and capsule bodies have c = 0.
"""

from __future__ import annotations

import math
import re
import tomllib
from pathlib import Path

import numpy as np

from ..errors import SceneError
from . import decompose, generators, meshes, terrain, timeline
from ..solvers import SOLVERS  # the registry itself (Taichi-free), so names and options cannot drift
from .hull import MAX_HULL_VERTICES, HullError, hull_vertices, reduce_to_hull
from .massprops import MassProperties, combine, part_mass_properties
from .rotations import quat_to_matrix
from .schema import Context, Reader
from .spec import DEFAULT_PIECES, MAX_PIECES, BodySpec, MeshSpec, PlaneSpec, Scene, ShapeSpec, SolverSpec, WorldSpec

SOLVER_NAMES = tuple(SOLVERS)
SOLVER_OPTIONS = {name: tuple(info.defaults) for name, info in SOLVERS.items()}
"""Options each solver takes, from the solver registry, so a misplaced option fails at load time
with its entry, not later in ``World``."""
GENERATOR_KINDS = ("stack", "pyramid", "grid", "wall", "rain")
EVENT_KINDS = timeline.EVENT_KINDS
EFFECTS = ("friction", "restitution")
"""Optional contact effects a scene may call for (``effects = [...]``); the engine compiles the others away."""
PART_SHAPES = ("box", "sphere", "capsule", "hull")
SOLID_SHAPES = PART_SHAPES + ("compound",)
BODY_SHAPES = SOLID_SHAPES + ("mesh",)
"""A ``[[body]]`` may be a decomposed mesh; in ``[[static]]``, ``mesh`` is a static triangle mesh."""
STATIC_SHAPES = ("plane", "mesh") + SOLID_SHAPES

DEFAULT_DENSITY = 1000.0  # [kg/m^3]
DEFAULT_FRICTION = 0.5
DEFAULT_RESTITUTION = 0.0
MAX_BODIES = 1_000_000
"""Sanity limit on the bodies of one scene (catches a typo such as count = 1e9 before memory runs out)."""
MAX_ITERATIONS = timeline.MAX_ITERATIONS
MAX_HEIGHTFIELD_CELLS = 2048
"""Per axis; 2048 x 2048 cells is 8.4 million triangles."""

TOP_KEYS = ("description", "world", "solver", "static", "body", "generate", "event", "effects")
WORLD_KEYS = ("gravity", "dt", "substeps", "contact_hertz", "duration")
SOLVER_OPTION_KEYS = ("shuffle", "relaxation", "seed")
SOLVER_KEYS = ("name", "iterations") + SOLVER_OPTION_KEYS
SHAPE_KEYS = {
    "box": ("half_extents",),
    "sphere": ("radius",),
    "capsule": ("radius", "half_height"),
    "hull": ("vertices", "path", "scale"),
    "compound": ("parts",),
    "mesh": ("path", "generator", "scale", "decomposition"),
}
SHAPE_REQUIRED = {"box": ("half_extents",), "sphere": ("radius",), "capsule": ("radius", "half_height"),
                  "hull": (), "compound": ("parts",), "mesh": ()}
BODY_KEYS = ("shape", "position", "orientation", "linear_velocity", "angular_velocity", "density", "mass",
             "friction", "restitution", "name", "static", "breakable", "strength", "pieces")
DECOMPOSITION_KEYS = ("threshold", "max_hulls", "seed", "max_hull_vertices", "timeout", "on_failure")
MAX_SEED = 2**31 - 1
STATIC_SOLID_KEYS = ("shape", "position", "orientation", "friction", "restitution", "name")
PART_KEYS = ("shape", "position", "orientation", "density")
PLANE_KEYS = ("shape", "normal", "offset", "friction", "restitution")
MESH_KEYS = ("shape", "path", "heightfield", "position", "orientation", "scale", "friction", "restitution", "name")
HEIGHTFIELD_KEYS = {
    "sines": ("function", "amplitude", "frequency", "size", "cells"),
    "noise": ("function", "amplitude", "size", "cells", "seed", "smoothing"),
}
HEIGHTFIELD_REQUIRED = {"sines": ("amplitude", "size", "cells"), "noise": ("amplitude", "size", "cells", "seed")}
MATERIAL_KEYS = ("density", "mass", "friction", "restitution", "name")
RAIN_KEYS = ("count", "region", "shapes", "weights", "half_extents", "half_extent_range", "orientation", "seed",
             "linear_velocity", "angular_velocity") + MATERIAL_KEYS
GENERATOR_KEYS = {
    "stack": ("kind", "count", "half_extents", "size", "position", "gap", "jitter", "seed") + MATERIAL_KEYS,
    "pyramid": ("kind", "base", "half_extents", "size", "position", "gap", "layout") + MATERIAL_KEYS,
    "grid": ("kind", "counts", "spacing", "origin", "shapes", "weights", "half_extents", "half_extent_range",
             "orientation", "seed") + MATERIAL_KEYS,
    "wall": ("kind", "rows", "columns", "half_extents", "size", "position", "direction", "bond", "gap")
    + MATERIAL_KEYS,
    "rain": ("kind",) + RAIN_KEYS,
}
GENERATOR_REQUIRED = {"stack": ("count", "position"), "pyramid": ("base", "position"),
                      "grid": ("counts", "spacing", "origin"), "wall": ("rows", "columns", "position"),
                      "rain": ("count", "region", "seed")}
EVENT_KEYS = {  # kind -> (allowed keys, required keys)
    "drop": (("time", "kind") + RAIN_KEYS, ("time", "kind", "count", "region", "seed")),
    "set_velocity": (("time", "kind", "bodies", "linear_velocity", "angular_velocity"), ("time", "kind", "bodies")),
    "impulse": (("time", "kind", "bodies", "impulse", "point"), ("time", "kind", "bodies", "impulse")),
    "remove": (("time", "kind", "bodies"), ("time", "kind", "bodies")),
    "solver": (("time", "kind", "name", "iterations") + SOLVER_OPTION_KEYS, ("time", "kind", "name")),
    "iterations": (("time", "kind", "iterations"), ("time", "kind", "iterations")),
    "gravity": (("time", "kind", "gravity"), ("time", "kind", "gravity")),
    "effects": (("time", "kind", "effects"), ("time", "kind", "effects")),
    "fracture": (("time", "kind", "bodies", "pieces", "seed", "impulse"), ("time", "kind", "bodies")),
}


# ---------------------------------------------------------------------------- entry points
def load_scene(path) -> Scene:
    """Load and validate a TOML scene file; the error source is ``path``."""
    source = str(path)
    try:
        file = Path(path)
    except TypeError:
        raise SceneError(f"scene path must be a string or path, got {type(path).__name__}", source=source) from None
    try:
        raw = file.read_bytes()
    except FileNotFoundError:
        raise SceneError("scene file not found", source=source) from None
    except IsADirectoryError:
        raise SceneError("scene path is a directory, not a file", source=source) from None
    except OSError as exc:
        raise SceneError(f"cannot read scene file: {exc.strerror or exc}", source=source) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SceneError(f"scene file is not UTF-8 text (bad byte at offset {exc.start})", source=source) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        msg = str(exc)
        where = re.search(r"at line (\d+), column (\d+)", msg)
        entry = f"line {where.group(1)}, column {where.group(2)}" if where else None
        problem = re.sub(r"\s*\(at line \d+, column \d+\)", "", msg) if where else msg
        raise SceneError(f"TOML syntax error: {problem}", source=source, entry=entry) from None
    return scene_from_dict(data, source=source, base_dir=file.parent)


def scene_from_dict(data, source: str = "<dict>", base_dir=None) -> Scene:
    """Validate and expand a scene given as a dict with the TOML file's structure.

    Relative mesh paths resolve against ``base_dir`` (the current directory when None).
    """
    try:
        base = Path(base_dir) if base_dir is not None else Path.cwd()
    except TypeError:
        raise SceneError(f"base_dir must be a path, got {type(base_dir).__name__}", source=str(source)) from None
    ctx = Context(source=str(source), base_dir=base)
    # extreme but finite inputs (1e308) may overflow in arithmetic; every derived value is checked
    # for finiteness explicitly, so numpy's warnings would only be noise
    with np.errstate(all="ignore"):
        scene = _build(data, ctx)
    scene.warnings = list(ctx.warnings)
    return scene


def _build(data, ctx: Context) -> Scene:
    top = Reader(data, "", ctx)
    top.check_keys(TOP_KEYS, what="the top level")
    scene = Scene(source=ctx.source, description=top.string("description", ""))
    scene.world = _read_world(top.table("world", None))
    scene.solver = _read_solver(top.table("solver", None))
    names: dict[str, str] = {}
    for r in top.tables("body"):
        body = _read_solid(r, static_section=False)
        _claim_name(names, body.name, r, "name")
        scene.bodies.append(body)
    for r in top.tables("generate"):
        bodies = _read_generator(r, budget=MAX_BODIES - len(scene.bodies))
        for body in bodies:
            _claim_name(names, body.name, r, "name")
        scene.bodies.extend(bodies)
    for r in top.tables("static"):
        kind = r.string("shape", choices=STATIC_SHAPES, what="static shape")
        if kind == "plane":
            scene.planes.append(_read_plane(r))
        elif kind == "mesh":
            mesh = _read_mesh(r)
            _claim_name(names, mesh.name, r, "name")
            scene.meshes.append(mesh)
        else:
            body = _read_solid(r, static_section=True)
            _claim_name(names, body.name, r, "name")
            scene.bodies.append(body)
    if len(scene.bodies) > MAX_BODIES:
        raise SceneError(f"scene has {len(scene.bodies)} bodies; at most {MAX_BODIES} are supported", source=ctx.source)
    scene.effects = top.string_set("effects", EFFECTS, what="effect") if top.has("effects") else EFFECTS
    scene.events = timeline.read_events(
        top.tables("event"),
        duration=scene.world.duration,
        bodies=scene.bodies,
        mesh_names={m.name for m in scene.meshes if m.name is not None},
        event_keys=EVENT_KEYS,
        read_drop=lambda r, budget: _expanded(r, "rain", budget),
        read_solver=_read_solver_change,
        read_effects=lambda r: r.string_set("effects", EFFECTS, what="effect"),
        claim_name=lambda name, r, key: _claim_name(names, name, r, key),
        budget=MAX_BODIES - len(scene.bodies),
    )
    return scene


def _claim_name(names: dict, name, r: Reader, key: str) -> None:
    if name is None:
        return
    if name in names:
        raise r.error(f"duplicate name {name!r} (already used by {names[name]})", key)
    names[name] = r.entry


# ---------------------------------------------------------------------------- world, solver
def _read_world(r: Reader | None) -> WorldSpec:
    if r is None:
        return WorldSpec()
    r.check_keys(WORLD_KEYS, what="[world]")
    return WorldSpec(
        gravity=r.vector("gravity", 3, (0.0, 0.0, -9.81)),
        dt=r.real("dt", 1.0 / 60.0, positive=True),
        substeps=r.integer("substeps", 1, minimum=1, maximum=10_000),
        contact_hertz=r.real("contact_hertz", None, positive=True),
        duration=r.real("duration", None, positive=True),
    )


def _read_solver(r: Reader | None) -> SolverSpec:
    if r is None:
        return SolverSpec()
    r.check_keys(SOLVER_KEYS, what="[solver]")
    name = r.string("name", "pgs", choices=SOLVER_NAMES, what="solver")
    return SolverSpec(
        name=name,
        iterations=r.integer("iterations", 10, minimum=1, maximum=MAX_ITERATIONS),
        options=_read_solver_options(r, name),
    )


def _read_solver_options(r: Reader, name: str) -> dict:
    """The options given for solver ``name`` (only those present: the solver fills in its defaults)."""
    for key in SOLVER_OPTION_KEYS:
        if r.has(key) and key not in SOLVER_OPTIONS[name]:
            takes = ", ".join(SOLVER_OPTIONS[name]) or "no options"
            raise r.error(f"option '{key}' does not apply to solver '{name}' (it takes: {takes})", key)
    options = {}
    if r.has("shuffle"):
        options["shuffle"] = r.boolean("shuffle")
    if r.has("relaxation"):
        options["relaxation"] = r.real("relaxation", low=0.0, high=2.0, open_low=True, open_high=True)
    if r.has("seed"):
        options["seed"] = r.integer("seed", minimum=0)
    return options


def _read_solver_change(r: Reader) -> tuple[str, int | None, dict]:
    """A ``solver`` event: the new solver's name, iteration count (None keeps it) and options."""
    name = r.string("name", choices=SOLVER_NAMES, what="solver")
    return name, r.integer("iterations", None, minimum=1, maximum=MAX_ITERATIONS), _read_solver_options(r, name)


# ---------------------------------------------------------------------------- shapes and bodies
def _load_mesh_file(r: Reader, key: str, process: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) of a mesh file read with trimesh (force='mesh'), cached per load."""
    path = r.file(key)
    cached = r.ctx.cache.get((path.resolve(), process))
    if cached is not None:
        return cached
    try:
        vertices, faces = meshes.read_mesh_file(path, process=process)
    except meshes.MeshError as exc:
        raise r.error(str(exc), key) from None
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0 or vertices.ndim != 2 or vertices.shape[1] != 3:
        raise r.error(f"mesh file {path} contains no triangles", key)
    if not np.all(np.isfinite(vertices)):
        raise r.error(f"mesh file {path} has NaN or inf vertex coordinates", key)
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise r.error(f"mesh file {path} has triangle indices out of range", key)
    r.ctx.cache[(path.resolve(), process)] = (vertices, faces)
    return vertices, faces


def _read_shape(r: Reader, kind: str) -> ShapeSpec:
    """One convex shape in its own frame (the caller sets the local pose)."""
    if kind == "box":
        return ShapeSpec("box", half_extents=r.vector("half_extents", 3, positive=True))
    if kind == "sphere":
        return ShapeSpec("sphere", radius=r.real("radius", positive=True))
    if kind == "capsule":
        return ShapeSpec("capsule", radius=r.real("radius", positive=True),
                         half_height=r.real("half_height", positive=True))
    # hull
    source = r.exclusive("vertices", "path")
    scale = r.scalar_or_vector("scale", 3, 1.0, positive=True)
    with np.errstate(all="ignore"):
        try:
            if source == "vertices":
                points = r.points("vertices") * scale
                if not np.all(np.isfinite(points)):
                    raise HullError("scaled hull vertices overflow")
                vertices = hull_vertices(points)
            else:
                mesh_vertices, _ = _load_mesh_file(r, "path")
                vertices = reduce_to_hull(mesh_vertices * scale)
        except HullError as exc:
            raise r.error(str(exc), source) from None
    return ShapeSpec("hull", vertices=vertices)


def _read_solid(r: Reader, *, static_section: bool) -> BodySpec:
    """A ``[[body]]`` entry, or a convex ``[[static]]`` entry (box/sphere/capsule/hull/compound)."""
    kind = r.string("shape", choices=SOLID_SHAPES if static_section else BODY_SHAPES, what="shape")
    base = STATIC_SOLID_KEYS if static_section else BODY_KEYS
    r.check_keys(base + SHAPE_KEYS[kind], required=("position",) + SHAPE_REQUIRED[kind],
                 what=f"a {'static ' if static_section else ''}{kind}")
    decomposition = None
    if kind == "compound":
        parts = r.tables("parts")
        if not parts:
            raise r.error("a compound needs at least one part", "parts")
        shapes, densities = [], []
        for p in parts:
            pk = p.string("shape", choices=PART_SHAPES, what="compound part shape")
            p.check_keys(PART_KEYS + SHAPE_KEYS[pk], required=SHAPE_REQUIRED[pk], what=f"a {pk} part")
            shape = _read_shape(p, pk)
            shape.local_position = p.vector("position", 3, (0.0, 0.0, 0.0))
            shape.local_orientation = p.quaternion("orientation")
            shapes.append(shape)
            densities.append(p.real("density", None, positive=True))
    elif kind == "mesh":
        shapes, decomposition = _read_mesh_body(r)
        densities = [None] * len(shapes)
    else:
        shapes, densities = [_read_shape(r, kind)], [None]
    position = r.vector("position", 3)
    orientation = r.quaternion("orientation")
    static = static_section or r.boolean("static", False)
    r.exclusive("density", "mass", required=False)
    density = r.real("density", DEFAULT_DENSITY, positive=True)  # a static section rejected the key already
    mass = r.real("mass", None, positive=True)
    linear_velocity = r.vector("linear_velocity", 3, (0.0, 0.0, 0.0))
    angular_velocity = r.vector("angular_velocity", 3, (0.0, 0.0, 0.0))
    if static and (np.any(linear_velocity) or np.any(angular_velocity)):
        key = "linear_velocity" if np.any(linear_velocity) else "angular_velocity"
        raise r.error("a static body cannot move; remove the velocity or set static = false", key)
    with np.errstate(all="ignore"):
        if decomposition is not None:
            parts = decomposition.parts(mass if mass is not None else density * decomposition.mesh_volume)
        else:
            parts = part_mass_properties(shapes, [d if d is not None else density for d in densities])
        mp = parts[0] if len(parts) == 1 else combine(parts)
        if not (math.isfinite(mp.mass) and mp.mass > 0 and np.all(np.isfinite(mp.inertia))):
            raise r.error(f"mass properties are not finite and positive (mass {mp.mass:g} kg); check sizes and density")
        if mass is not None and decomposition is None:
            factor = mass / mp.mass
            mp, parts = mp.scaled(factor), [p.scaled(factor) for p in parts]
        for shape, part in zip(shapes, parts):
            shape.local_position = shape.local_position - mp.com
            if len(shapes) >= 2:  # each shape's share, for a fracture into the shapes (fracture.py)
                shape.piece_mass, shape.piece_com, shape.piece_inertia = part.mass, part.com - mp.com, part.inertia
        com_world = position + quat_to_matrix(orientation) @ mp.com
        if not (np.all(np.isfinite(com_world)) and np.all(np.isfinite(mp.inertia)) and math.isfinite(mp.mass)):
            raise r.error("position or mass properties overflow to inf")
    name = r.string("name", None)
    if name is not None and not name:
        raise r.error("a name must not be empty", "name")
    breakable, strength, pieces = _read_breakable(r, static)
    return BodySpec(
        shapes=shapes,
        position=com_world,
        orientation=orientation,
        linear_velocity=linear_velocity,
        angular_velocity=angular_velocity,
        mass=float(mp.mass),
        inertia=mp.inertia,
        static=static,
        friction=r.real("friction", DEFAULT_FRICTION, nonnegative=True),
        restitution=r.real("restitution", DEFAULT_RESTITUTION, low=0.0, high=1.0),
        name=name,
        breakable=breakable,
        strength=strength,
        pieces=pieces,
    )


def _read_breakable(r: Reader, static: bool) -> tuple[bool, float | None, int]:
    """``breakable``, ``strength`` [N s] (required with it) and ``pieces`` (only with it)."""
    breakable = r.boolean("breakable", False)
    if not breakable:
        for key in ("strength", "pieces"):
            if r.has(key):
                raise r.error(f"'{key}' applies only to breakable bodies (set breakable = true)", key)
        return False, None, DEFAULT_PIECES
    if static:
        raise r.error("a static body cannot be breakable", "breakable")
    if not r.has("strength"):
        raise r.error("a breakable body needs 'strength' [N s]: the normal impulse one contact may pass to it in "
                      "one step before it breaks", "strength")
    return True, r.real("strength", positive=True), r.integer("pieces", DEFAULT_PIECES, minimum=2, maximum=MAX_PIECES)


# ---------------------------------------------------------------------------- non-convex bodies
def _read_mesh_body(r: Reader) -> tuple[list[ShapeSpec], "decompose.Decomposition | None"]:
    """A ``shape = "mesh"`` body: its hulls and their decomposition (None when it fell back to one hull)."""
    source = r.exclusive("path", "generator")
    scale = r.scalar_or_vector("scale", 3, 1.0, positive=True)
    if source == "path":
        vertices, faces = _load_mesh_file(r, "path", process=False)  # checked_mesh processes it
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
def _read_plane(r: Reader) -> PlaneSpec:
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


def _read_mesh(r: Reader) -> MeshSpec:
    r.check_keys(MESH_KEYS, what="a static mesh")
    source = r.exclusive("path", "heightfield")
    position = r.vector("position", 3, (0.0, 0.0, 0.0))
    orientation = r.quaternion("orientation")
    scale = r.scalar_or_vector("scale", 3, 1.0, positive=True)
    if source == "path":
        vertices, triangles = _load_mesh_file(r, "path")
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


# ---------------------------------------------------------------------------- generators
def _read_material(r: Reader) -> generators.Material:
    r.exclusive("density", "mass", required=False)
    name = r.string("name", None)
    if name is not None and not name:
        raise r.error("a name prefix must not be empty", "name")
    return generators.Material(
        density=r.real("density", DEFAULT_DENSITY, positive=True),
        mass=r.real("mass", None, positive=True),
        friction=r.real("friction", DEFAULT_FRICTION, nonnegative=True),
        restitution=r.real("restitution", DEFAULT_RESTITUTION, low=0.0, high=1.0),
        name=name,
    )


def _read_box_size(r: Reader) -> np.ndarray:
    key = r.exclusive("half_extents", "size")
    v = r.scalar_or_vector(key, 3, positive=True)
    return v if key == "half_extents" else v / 2.0


def _need_seed(r: Reader, why: str) -> int:
    if not r.has("seed"):
        raise r.error(f"missing required key 'seed' ({why} draws random numbers)", "seed")
    return r.integer("seed", minimum=0)


def _check_budget(r: Reader, key: str, count: int, budget: int) -> None:
    if count > budget:
        raise r.error(f"would generate {count} bodies; a scene holds at most {MAX_BODIES}", key)


def _read_generator(r: Reader, *, budget: int) -> list[BodySpec]:
    kind = r.string("kind", choices=GENERATOR_KINDS, what="generator kind")
    r.check_keys(GENERATOR_KEYS[kind], required=("kind",) + GENERATOR_REQUIRED[kind], what=f"a '{kind}' generator")
    return _expanded(r, kind, budget)


def _expanded(r: Reader, kind: str, budget: int) -> list[BodySpec]:
    """The bodies of a generator entry (or of a drop event, kind 'rain') whose keys are checked."""
    material = _read_material(r)
    try:
        with np.errstate(all="ignore"):
            bodies = _expand(r, kind, material, budget)
    except generators.GeneratorError as exc:
        raise r.error(str(exc), exc.key) from None
    except HullError as exc:
        raise r.error(f"a generated hull is invalid: {exc}") from None
    for body in bodies:
        if not (np.all(np.isfinite(body.position)) and math.isfinite(body.mass) and body.mass > 0
                and np.all(np.isfinite(body.inertia))):
            raise r.error("generated positions or mass properties are not finite and positive; check sizes, "
                          "spacing and density")
    return bodies


def _expand(r: Reader, kind: str, material: generators.Material, budget: int) -> list[BodySpec]:
    if kind == "stack":
        count = r.integer("count", minimum=1)
        _check_budget(r, "count", count, budget)
        half = _read_box_size(r)
        jitter = r.real("jitter", 0.0, nonnegative=True)
        seed = _need_seed(r, "jitter > 0") if jitter > 0 else r.integer("seed", None, minimum=0)
        return generators.stack(count, half, r.vector("position", 3), gap=r.real("gap", 0.0, nonnegative=True),
                                jitter=jitter, seed=seed, material=material)
    if kind == "wall":
        rows = r.integer("rows", minimum=1)
        columns = r.integer("columns", minimum=1)
        _check_budget(r, "rows", min(rows, 10**7) * min(columns, 10**7), budget)
        return generators.wall(rows, columns, _read_box_size(r), r.vector("position", 3),
                               direction=r.string("direction", "x", choices=generators.WALL_DIRECTIONS,
                                                  what="wall direction"),
                               bond=r.string("bond", "stack", choices=generators.WALL_BONDS, what="wall bond"),
                               gap=r.real("gap", 0.0, nonnegative=True), material=material)
    if kind == "rain":
        return _read_rain(r, material, budget)
    if kind == "pyramid":
        base = r.integer("base", minimum=1)
        layout = r.string("layout", "2d", choices=("2d", "3d"), what="pyramid layout")
        _check_budget(r, "base", generators.pyramid_count(min(base, 10**7), layout), budget)
        return generators.pyramid(base, _read_box_size(r), r.vector("position", 3),
                                  gap=r.real("gap", 0.0, nonnegative=True), layout=layout, material=material)
    # grid
    counts = r.int_vector("counts", 3, minimum=1)
    _check_budget(r, "counts", int(np.prod([min(int(c), 10**7) for c in counts])), budget)
    spacing = r.scalar_or_vector("spacing", 3, positive=True)
    origin = r.vector("origin", 3)
    shapes, weights, half_extents, half_range, orientation = _read_shape_mix(r, "identity", "grid")
    random_reasons = [why for why, used in (("more than one shape", len(shapes) > 1),
                                            ("half_extent_range", half_range is not None),
                                            ("orientation = 'random'", isinstance(orientation, str) and orientation == "random"),
                                            ("a hull shape", "hull" in shapes)) if used]
    seed = _need_seed(r, random_reasons[0]) if random_reasons else r.integer("seed", None, minimum=0)
    return generators.grid(counts, spacing, origin, shapes=shapes, weights=weights, half_extents=half_extents,
                           half_extent_range=half_range, orientation=orientation, seed=seed, material=material)


def _read_rain(r: Reader, material: generators.Material, budget: int) -> list[BodySpec]:
    count = r.integer("count", minimum=1)
    _check_budget(r, "count", count, budget)
    region = r.points("region")
    if len(region) != 2:
        raise r.error(f"expected [[x0, y0, z0], [x1, y1, z1]] (two corners), got {len(region)} points", "region")
    low, high = region
    if not np.all(low < high):
        raise r.error(f"region corners must satisfy low < high on every axis, got low {low.tolist()} and high "
                      f"{high.tolist()}", "region")
    shapes, weights, half_extents, half_range, orientation = _read_shape_mix(r, "random", "rain")
    linear_velocity = r.vector("linear_velocity", 3, (0.0, 0.0, 0.0))
    angular_velocity = r.vector("angular_velocity", 3, (0.0, 0.0, 0.0))
    return generators.rain(count, low, high, shapes=shapes, weights=weights, half_extents=half_extents,
                           half_extent_range=half_range, orientation=orientation,
                           seed=r.integer("seed", minimum=0), linear_velocity=linear_velocity,
                           angular_velocity=angular_velocity, material=material)


def _read_shape_mix(r: Reader, default_orientation: str, label: str):
    """shapes, weights, half_extents or half_extent_range, orientation: the keys grid and rain share."""
    shapes = r.choice_list("shapes", generators.GRID_SHAPES, what=f"{label} shape") if r.has("shapes") else ["box"]
    weights = None
    if r.has("weights"):
        if len(shapes) < 2:
            raise r.error("weights need at least two entries in 'shapes'", "weights")
        weights = r.vector("weights", len(shapes), nonnegative=True)
        if not weights.sum() > 0:
            raise r.error("weights must not all be zero", "weights")
    size_key = r.exclusive("half_extents", "half_extent_range")
    half_extents = half_range = None
    if size_key == "half_extents":
        half_extents = r.scalar_or_vector("half_extents", 3, positive=True)
    else:
        half_range = r.vector("half_extent_range", 2, positive=True)
        if half_range[0] > half_range[1]:
            raise r.error(f"expected [low, high] with low <= high, got {half_range.tolist()}", "half_extent_range")
    orientation = default_orientation
    if r.has("orientation"):
        if isinstance(r.data["orientation"], str):
            orientation = r.string("orientation", choices=("identity", "random"), what=f"{label} orientation")
        else:
            orientation = r.quaternion("orientation")
    return shapes, weights, half_extents, half_range, orientation


__all__ = ["load_scene", "scene_from_dict", "SOLVER_NAMES", "SOLVER_OPTIONS", "GENERATOR_KINDS", "EVENT_KINDS",
           "EFFECTS", "MAX_BODIES"]
