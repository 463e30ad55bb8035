"""Runs CoACD on one mesh in its own process: ``python -m sandbox.scene.decompose_worker IN OUT``.

IN is an .npz with ``vertices`` (V, 3) float64, ``faces`` (F, 3) int32 and ``options``
(a JSON string of ``coacd.run_coacd`` keyword arguments); OUT receives ``hull_<i>``
vertex arrays and ``count``. Only numpy and coacd are imported here: CoACD aborts its
process on bad input (docs/apis.md section 2), and this process is the one it kills.
"""

from __future__ import annotations

import json
import sys

import numpy as np


def main(argv: list[str]) -> int:
    import coacd

    src, dst = argv
    data = np.load(src, allow_pickle=False)
    options = json.loads(str(data["options"]))
    coacd.set_log_level("error")
    mesh = coacd.Mesh(np.ascontiguousarray(data["vertices"], dtype=np.float64),
                      np.ascontiguousarray(data["faces"], dtype=np.int32))
    parts = coacd.run_coacd(mesh, **options)
    arrays = {f"hull_{i}": np.asarray(v, dtype=np.float64) for i, (v, _) in enumerate(parts)}
    np.savez(dst, count=np.int64(len(parts)), **arrays)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
