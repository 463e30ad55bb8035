"""CoACD decomposition time of every mesh the shipped scenes use, cold and cached.

    python benchmarks/coacd_timings.py [--scenes scenes] [--cache DIR]

For each distinct (mesh, decomposition options) in a ``shape = "mesh"`` body of
``scenes/*.toml``: *cold* is ``decompose`` into an empty cache (child process start,
CoACD, overlap repair, mass partition, cache write), *cached* is the same call again
(a file read). The cold run uses a fresh temporary cache unless ``--cache`` is given.
Wall-clock times; CoACD runs single-threaded in effect on a loaded 2-core machine.
"""

from __future__ import annotations

import argparse
import platform
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

from sandbox.scene import decompose, meshes
from sandbox.scene.hull import MAX_HULL_VERTICES


def shipped_meshes(folder: Path) -> list:
    """[labels, trimesh, DecomposeOptions] for every distinct mesh body of the scenes in ``folder``."""
    found: dict[str, list] = {}
    for path in sorted(folder.glob("*.toml")):
        data = tomllib.loads(path.read_text())
        for i, body in enumerate(data.get("body", [])):
            if body.get("shape") != "mesh":
                continue
            if "path" in body:
                v, f = meshes.read_mesh_file(path.parent / body["path"])
                what = body["path"]
            else:
                params = {k: v for k, v in body["generator"].items() if k != "kind"}
                v, f = meshes.generate(body["generator"]["kind"], params)
                what = body["generator"]["kind"]
            mesh = meshes.checked_mesh(np.asarray(v) * body.get("scale", 1.0), f)
            d = body.get("decomposition", {})
            options = decompose.DecomposeOptions(threshold=d.get("threshold", decompose.DEFAULT_THRESHOLD),
                                                 max_hulls=d.get("max_hulls"), seed=d.get("seed", 0),
                                                 max_hull_vertices=d.get("max_hull_vertices", MAX_HULL_VERTICES))
            key = decompose.cache_key(mesh.vertices, mesh.faces, options)
            label = f"{path.stem} body[{i}]"
            if key in found:
                found[key][0].append(label)
            else:
                found[key] = [[what, label], mesh, options]
    return list(found.values())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", default=str(Path(__file__).resolve().parent.parent / "scenes"))
    ap.add_argument("--cache", default=None, help="cache folder (default: a fresh temporary one, so runs are cold)")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="coacd-bench-") as tmp:
        cache = Path(a.cache) if a.cache else Path(tmp)
        print(f"CoACD timings, {platform.machine()} {platform.processor() or ''}, {time.strftime('%Y-%m-%d %H:%M')}, "
              f"cache {cache}")
        print("| mesh | V / F | threshold, max hulls | hulls | covered | repaired pairs | cold [s] | cached [ms] |")
        print("|---|---|---|---|---|---|---|---|")
        for labels, mesh, options in shipped_meshes(Path(a.scenes)):
            label = f"{labels[0]} ({', '.join(labels[1:])})"
            start = time.perf_counter()
            cold = decompose.decompose(mesh, options, cache=cache)
            t_cold = time.perf_counter() - start
            start = time.perf_counter()
            warm = decompose.decompose(mesh, options, cache=cache)
            t_warm = time.perf_counter() - start
            state = "" if not cold.cached else " (was already cached)"
            assert warm.cached
            print(f"| {label} | {len(mesh.vertices)} / {len(mesh.faces)} | {options.threshold:g}, "
                  f"{options.max_hulls or '-'} | {len(cold.hulls)} | {cold.covered:.4f} | {cold.repaired_pairs} | "
                  f"{t_cold:.2f}{state} | {t_warm * 1e3:.1f} |", flush=True)


if __name__ == "__main__":
    main()
