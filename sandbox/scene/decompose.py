"""Approximate convex decomposition of a closed mesh into the hulls of one compound body.

CoACD (Wei et al., "Approximate Convex Decomposition for 3D Meshes with
Collision-Aware Concavity and Tree Search", SIGGRAPH 2022) cuts the mesh with
planes and returns the convex hull of each part. Around it:

1. **Isolation.** CoACD aborts its process on bad input and can run for minutes,
   so it runs in a child process (``python -m sandbox.scene.decompose_worker``)
   with a timeout; a crash, a timeout or an exception becomes one
   ``DecompositionError`` saying why, and the caller's process lives on. Meshes
   are checked first (``meshes.checked_mesh``).
2. **Cache.** The result (after steps 3 and 4) is stored on disk under
   ``cache_dir()`` as ``<sha256>.npz``, keyed by the mesh's vertex and face bytes,
   the options that change the output (threshold, max hulls, seed, hull vertex
   limit), CoACD's version and ``FORMAT_VERSION``; a second load of the same mesh
   reads the file and never starts CoACD. Files are written atomically (temp file,
   then rename); an unreadable one is recomputed.
3. **Overlap repair.** Hulls of parts cut by one plane tree lie in disjoint convex
   cells and only touch, but CoACD's merge step (``max_hulls``) can merge two hulls
   into one that overlaps a third (measured: 4 % of a bowl's volume). Pieces that
   overlap would be pushed apart violently when the body fractures, so every pair
   overlapping by more than ``OVERLAP_TOLERANCE`` (relative to the mesh's extent)
   is cut apart along its separating-axis direction of least overlap, at the middle
   of the overlap (``polytope.penetration_depth``, ``clip_convex``). Hulls only
   shrink, so one pass over the pairs leaves none overlapping.
4. **Mass partition.** Hulls bulge out of concave meshes (a torus's hulls hold 8 %
   more volume than the torus), so hull volumes do not give the body's mass. Each
   hull instead carries the mass properties of the mesh's material inside it
   (``mesh ∩ hull``, a manifold3d boolean): since the hulls do not overlap, these
   cells partition the mesh, and the body's mass, centre of mass and inertia are
   their sum. A fracture into the hulls then conserves momentum exactly (the
   pieces partition the parent), while collisions use the hulls. If the hulls miss
   a sliver of the mesh (CoACD's vertex decimation shrinks hulls slightly; the
   shipped meshes keep over 99.5 % of their volume), the cells' density is scaled
   so the total mass is still density x the mesh's volume (``covered`` says how
   much was inside).

``decompose_async`` runs the same in a worker thread and returns a Future, for a
caller (a UI) that must not block while CoACD runs.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import SandboxError
from ..polytope import GeometryError, clip_convex, penetration_depth
from .hull import MAX_HULL_VERTICES, HullError, usable_hull
from .massprops import MassProperties, combine

FORMAT_VERSION = 1
"""Bump when the cached content or its post-processing changes: old files are then ignored."""
DEFAULT_THRESHOLD = 0.05
"""CoACD's own default concavity threshold (normalised units, 0.01 to 1): smaller gives more, tighter hulls."""
DEFAULT_TIMEOUT = 300.0
"""[s] A decomposition still running after this is killed (a 2304-triangle torus needs ~10 s on one core)."""
OVERLAP_TOLERANCE = 1e-6
"""[1] Hull pairs overlapping by more than this times the mesh's extent are cut apart (step 3 above);
touching hulls overlap by rounding only (~1e-15)."""


class DecompositionError(SandboxError):
    """CoACD could not decompose a mesh (crash, timeout, nothing usable); the message says why."""


@dataclass(frozen=True)
class DecomposeOptions:
    threshold: float = DEFAULT_THRESHOLD
    max_hulls: int | None = None  # None: as many as the threshold needs
    seed: int = 0
    max_hull_vertices: int = MAX_HULL_VERTICES  # CoACD decimates each hull to at most this many vertices
    timeout: float = DEFAULT_TIMEOUT  # [s]; not part of the cache key

    def key_fields(self) -> dict:
        return {"threshold": float(self.threshold), "max_hulls": self.max_hulls, "seed": int(self.seed),
                "max_hull_vertices": int(self.max_hull_vertices)}

    def coacd_kwargs(self) -> dict:
        return {"threshold": float(self.threshold), "max_convex_hull": -1 if self.max_hulls is None else int(self.max_hulls),
                "seed": int(self.seed), "decimate": True, "max_ch_vertex": int(self.max_hull_vertices)}


@dataclass
class Decomposition:
    """Hulls of one mesh and the mass of the mesh inside each (density 1), in the mesh's frame."""

    hulls: list  # (V_i, 3) hull vertices [m]
    cell_volume: np.ndarray  # (H,) [m^3] the mesh's volume inside each hull
    cell_com: np.ndarray  # (H, 3) [m] its centroid
    cell_inertia: np.ndarray  # (H, 3, 3) [kg m^2 per kg/m^3] about cell_com, at density 1
    mesh_volume: float  # [m^3]
    repaired_pairs: int = 0  # hull pairs cut apart (step 3)
    seconds: float = 0.0  # [s] wall time of the cold decomposition (CoACD and steps 3-4)
    cached: bool = False  # True when this call read the cache
    key: str = ""
    notes: list = field(default_factory=list)

    @property
    def covered(self) -> float:
        """Fraction of the mesh's volume inside the hulls."""
        return float(self.cell_volume.sum() / self.mesh_volume)

    def parts(self, mass: float) -> list[MassProperties]:
        """Mass properties of each hull's share when the body weighs ``mass`` [kg] (uniform density)."""
        rho = mass / float(self.cell_volume.sum())
        return [MassProperties(float(rho * v), c.copy(), rho * j)
                for v, c, j in zip(self.cell_volume, self.cell_com, self.cell_inertia)]

    def body_mass_properties(self, mass: float) -> MassProperties:
        parts = self.parts(mass)
        return parts[0] if len(parts) == 1 else combine(parts)


def cache_dir() -> Path:
    """``$SANDBOX_CACHE/coacd``, else ``$XDG_CACHE_HOME`` or ``~/.cache``, ``/mass-splitting-sandbox/coacd``."""
    root = os.environ.get("SANDBOX_CACHE")
    if root:
        return Path(root) / "coacd"
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "mass-splitting-sandbox" / "coacd"


INSTALL_HINT = ("pip install coacd shapely manifold3d (dependencies of mass-splitting-sandbox: "
                "the install is incomplete)")


def coacd_version() -> str:
    """The installed CoACD's version; DecompositionError when it is not installed."""
    from importlib import metadata

    try:
        return metadata.version("coacd")
    except metadata.PackageNotFoundError:
        raise DecompositionError(f"CoACD is not installed: {INSTALL_HINT}") from None


def cache_key(vertices: np.ndarray, faces: np.ndarray, options: DecomposeOptions) -> str:
    h = hashlib.sha256()
    meta = {"format": FORMAT_VERSION, "coacd": coacd_version(), **options.key_fields()}
    h.update(json.dumps(meta, sort_keys=True).encode())
    h.update(np.ascontiguousarray(vertices, dtype="<f8").tobytes())
    h.update(np.ascontiguousarray(faces, dtype="<i8").tobytes())
    return h.hexdigest()


def decompose(mesh, options: DecomposeOptions | None = None, *, cache: Path | None = None) -> Decomposition:
    """Decompose a checked ``trimesh.Trimesh`` (``meshes.checked_mesh``); cached on disk (module docstring).

    Raises DecompositionError when CoACD fails, times out or returns nothing usable.
    """
    options = options or DecomposeOptions()
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    key = cache_key(vertices, faces, options)
    folder = Path(cache) if cache is not None else cache_dir()
    path = folder / f"{key}.npz"
    found = _read_cache(path)
    if found is not None:
        found.cached, found.key = True, key
        return found
    start = time.perf_counter()
    raw = run_coacd(vertices, faces, options)
    result = _postprocess(mesh, raw, options)
    result.seconds = time.perf_counter() - start
    result.key = key
    _write_cache(path, result)
    return result


_pool: ThreadPoolExecutor | None = None


def decompose_async(mesh, options: DecomposeOptions | None = None, *, cache: Path | None = None) -> Future:
    """``decompose`` in a background thread (CoACD itself runs in a child process): returns a Future."""
    global _pool
    if _pool is None:
        _pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="sandbox-coacd")
    return _pool.submit(decompose, mesh, options, cache=cache)


# ---------------------------------------------------------------------------- CoACD in a child process
def run_coacd(vertices: np.ndarray, faces: np.ndarray, options: DecomposeOptions) -> list[np.ndarray]:
    """CoACD's hull vertex arrays, computed in a child process with ``options.timeout``."""
    root = str(Path(__file__).resolve().parents[2])  # the directory holding the sandbox package
    with tempfile.TemporaryDirectory(prefix="sandbox-coacd-") as tmp:
        src, dst = Path(tmp) / "in.npz", Path(tmp) / "out.npz"
        np.savez(src, vertices=np.asarray(vertices, dtype=np.float64), faces=np.asarray(faces, dtype=np.int32),
                 options=json.dumps(options.coacd_kwargs()))
        env = dict(os.environ)
        env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        try:
            proc = subprocess.run([sys.executable, "-m", "sandbox.scene.decompose_worker", str(src), str(dst)],
                                  capture_output=True, text=True, timeout=options.timeout, env=env)
        except subprocess.TimeoutExpired:
            raise DecompositionError(
                f"CoACD did not finish within {options.timeout:g} s (the decomposition 'timeout'); raise the timeout, "
                "raise 'threshold' or simplify the mesh") from None
        except OSError as exc:
            raise DecompositionError(f"cannot start the CoACD worker process: {exc}") from None
        if proc.returncode != 0:
            raise DecompositionError(f"CoACD failed: {_describe_exit(proc.returncode, proc.stderr)}")
        try:
            with np.load(dst, allow_pickle=False) as out:
                hulls = [np.asarray(out[f"hull_{i}"], dtype=np.float64) for i in range(int(out["count"]))]
        except (OSError, KeyError, ValueError) as exc:
            raise DecompositionError(f"CoACD's worker wrote no readable result ({exc})") from None
    if not hulls:
        raise DecompositionError("CoACD returned no hulls")
    return hulls


def _describe_exit(code: int, stderr: str) -> str:
    import signal

    lines = [line for line in (stderr or "").strip().splitlines() if line.strip()]
    tail = lines[-1].strip() if lines else "no message"
    if code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = f"signal {-code}"
        return f"the worker process was killed by {name} (CoACD aborts on input it cannot handle); last message: {tail}"
    return f"the worker process exited with status {code}; last message: {tail}"


# ---------------------------------------------------------------------------- steps 3 and 4
def _postprocess(mesh, raw: list[np.ndarray], options: DecomposeOptions) -> Decomposition:
    import trimesh

    try:
        import manifold3d  # noqa: F401  (trimesh's boolean engine, for the mass partition)
    except ImportError:
        raise DecompositionError(f"manifold3d is not installed: {INSTALL_HINT}") from None

    extent = float(np.ptp(np.asarray(mesh.vertices), axis=0).max())
    notes = []
    hulls = []
    for i, points in enumerate(raw):
        try:
            hulls.append(usable_hull(points, max_vertices=options.max_hull_vertices))
        except HullError as exc:
            notes.append(f"CoACD hull {i} dropped: {exc}")
    if not hulls:
        raise DecompositionError("every hull CoACD returned is degenerate: " + "; ".join(notes))
    hulls, repaired = _separate(hulls, OVERLAP_TOLERANCE * extent, options.max_hull_vertices)
    volumes, coms, inertias, kept = [], [], [], []
    for hull in hulls:
        solid = trimesh.convex.convex_hull(hull)
        with np.errstate(all="ignore"):
            cell = trimesh.boolean.intersection([mesh, solid], engine="manifold", check_volume=False)
        volume = float(cell.volume) if len(cell.faces) else 0.0
        if not volume > 1e-9 * float(mesh.volume):
            notes.append("a hull holding none of the mesh's material was dropped")
            continue
        mp = cell.mass_properties  # density 1
        kept.append(hull)
        volumes.append(volume)
        coms.append(np.asarray(mp.center_mass, dtype=np.float64))
        inertias.append(np.asarray(mp.inertia, dtype=np.float64))
    if not kept:
        raise DecompositionError("no hull holds any of the mesh's material")
    return Decomposition(kept, np.asarray(volumes), np.asarray(coms).reshape(-1, 3), np.asarray(inertias).reshape(-1, 3, 3),
                         float(mesh.volume), repaired_pairs=repaired, notes=notes)


def _separate(hulls: list, tolerance: float, max_vertices: int) -> tuple[list, int]:
    """Cut every pair of hulls overlapping by more than ``tolerance`` [m] apart (step 3)."""
    hulls = list(hulls)
    lo = [h.min(axis=0) for h in hulls]
    hi = [h.max(axis=0) for h in hulls]
    repaired = 0
    for i in range(len(hulls)):
        for j in range(i + 1, len(hulls)):
            if hulls[i] is None or hulls[j] is None:
                continue
            if np.any(lo[i] > hi[j] + tolerance) or np.any(lo[j] > hi[i] + tolerance):
                continue
            depth, axis = penetration_depth(hulls[i], hulls[j])
            if depth <= tolerance:
                continue
            # i lies on the low side of axis: keep axis . x <= mid for i, >= mid for j
            mid = 0.5 * (float((hulls[i] @ axis).max()) + float((hulls[j] @ axis).min()))
            a, b = clip_convex(hulls[i], axis, mid), clip_convex(hulls[j], -axis, -mid)
            for k, cut in ((i, a), (j, b)):
                try:
                    hulls[k] = None if cut is None else usable_hull(cut, max_vertices=max_vertices)
                except (HullError, GeometryError):
                    hulls[k] = None
                if hulls[k] is not None:
                    lo[k], hi[k] = hulls[k].min(axis=0), hulls[k].max(axis=0)
            repaired += 1
    return [h for h in hulls if h is not None], repaired


# ---------------------------------------------------------------------------- the disk cache
def _read_cache(path: Path) -> Decomposition | None:
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as f:
            if int(f["format"]) != FORMAT_VERSION:
                return None
            count = int(f["count"])
            return Decomposition(
                hulls=[np.asarray(f[f"hull_{i}"], dtype=np.float64) for i in range(count)],
                cell_volume=np.asarray(f["cell_volume"], dtype=np.float64),
                cell_com=np.asarray(f["cell_com"], dtype=np.float64),
                cell_inertia=np.asarray(f["cell_inertia"], dtype=np.float64),
                mesh_volume=float(f["mesh_volume"]),
                repaired_pairs=int(f["repaired_pairs"]),
                seconds=float(f["seconds"]),
                notes=json.loads(str(f["notes"])),
            )
    except Exception:  # noqa: BLE001 -- a damaged or foreign cache file is recomputed, never trusted
        return None


def _write_cache(path: Path, d: Decomposition) -> None:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=path.stem, suffix=".tmp.npz", dir=path.parent)
        os.close(fd)
        np.savez(tmp, format=np.int64(FORMAT_VERSION), count=np.int64(len(d.hulls)),
                 cell_volume=d.cell_volume, cell_com=d.cell_com, cell_inertia=d.cell_inertia,
                 mesh_volume=np.float64(d.mesh_volume), repaired_pairs=np.int64(d.repaired_pairs),
                 seconds=np.float64(d.seconds), notes=json.dumps(d.notes),
                 **{f"hull_{i}": h for i, h in enumerate(d.hulls)})
        os.replace(tmp, path)
    except OSError:
        pass  # a read-only cache directory only costs the next load another CoACD run
