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

This module holds the entry points and the order of the sections; each section has its
reader: ``keys`` (the schema as data: keys, defaults, limits), ``world_reader`` (``[world]``,
``[solver]``), ``body_reader`` (bodies and convex statics), ``mesh_reader`` (mesh files, mesh
bodies, planes, static meshes, height fields), ``generator_reader`` (``[[generate]]`` and drop
events) and ``timeline`` (``[[event]]``). ``Scene.load`` and ``Scene.from_dict`` are these
entry points, attached to ``Scene`` by the package (``scene/__init__.py``) so that ``spec.py``,
which every reader imports, never imports the loader back.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import numpy as np

from ..errors import SceneError
from . import timeline
from .body_reader import read_solid
from .generator_reader import read_drop, read_generator
from .keys import (DEFAULT_EFFECTS, EFFECTS, EVENT_KEYS, EVENT_KINDS, GENERATOR_KINDS, MAX_BODIES, SOLVER_NAMES,
                   SOLVER_OPTIONS, STATIC_SHAPES, TOP_KEYS)
from .mesh_reader import read_mesh, read_plane
from .schema import Context, Reader
from .spec import Scene
from .world_reader import read_solver, read_solver_change, read_world


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
        if where is None and "end of document" in msg:
            entry = f"end of file (line {max(1, len(text.splitlines()))})"
            problem = re.sub(r"\s*\(at end of document\)", "", msg)
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
    scene.world = read_world(top.table("world", None))
    scene.solver = read_solver(top.table("solver", None))
    names: dict[str, str] = {}
    for r in top.tables("body"):
        body = read_solid(r, static_section=False)
        _claim_name(names, body.name, r, "name")
        scene.bodies.append(body)
    for r in top.tables("generate"):
        bodies = read_generator(r, budget=MAX_BODIES - len(scene.bodies))
        for body in bodies:
            _claim_name(names, body.name, r, "name")
        scene.bodies.extend(bodies)
    for r in top.tables("static"):
        kind = r.string("shape", choices=STATIC_SHAPES, what="static shape")
        if kind == "plane":
            scene.planes.append(read_plane(r))
        elif kind == "mesh":
            mesh = read_mesh(r)
            _claim_name(names, mesh.name, r, "name")
            scene.meshes.append(mesh)
        else:
            body = read_solid(r, static_section=True)
            _claim_name(names, body.name, r, "name")
            scene.bodies.append(body)
    if len(scene.bodies) > MAX_BODIES:
        raise SceneError(f"scene has {len(scene.bodies)} bodies; at most {MAX_BODIES} are supported", source=ctx.source)
    scene.effects = top.string_set("effects", EFFECTS, what="effect") if top.has("effects") else DEFAULT_EFFECTS
    scene.events = timeline.read_events(
        top.tables("event"),
        duration=scene.world.duration,
        bodies=scene.bodies,
        mesh_names={m.name for m in scene.meshes if m.name is not None},
        event_keys=EVENT_KEYS,
        read_drop=read_drop,
        read_solver=read_solver_change,
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


__all__ = ["load_scene", "scene_from_dict", "SOLVER_NAMES", "SOLVER_OPTIONS", "GENERATOR_KINDS", "EVENT_KINDS",
           "EFFECTS", "MAX_BODIES"]
