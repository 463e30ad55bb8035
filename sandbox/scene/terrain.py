"""Height-field terrain: a regular triangulated grid z = f(x, y) as a static triangle mesh.

Grid layout (the same as the ``heightfield_pile`` anchor scene): ``cells = [nx, ny]``
cells over ``size = [sx, sy]`` metres centred on the origin, so
x = -sx/2 + i sx/nx (i = 0..nx), y = -sy/2 + j sy/ny (j = 0..ny), vertex index
j (nx + 1) + i. Each cell is split along its (x0, y0)-(x1, y1) diagonal into two
triangles wound counter-clockwise seen from +z, so the normals point up and the
solid side (for one-sided mesh triangles) is below.

Height functions:

* ``sines``: z = amplitude sin(fx x) cos(fy y), frequency [fx, fy] in rad/m.
  With amplitude 0.3, frequency 1, size [16, 16], cells [64, 64] this is the
  anchors' bumpy terrain exactly.
* ``noise``: seeded smooth random bumps: uniform heights in [-1, 1] per vertex
  (numpy ``default_rng(seed)``), ``smoothing`` passes of a 3 x 3 box filter
  (edges replicated), then scaled so the highest |z| equals ``amplitude``.
"""

from __future__ import annotations

import numpy as np

FUNCTIONS = ("sines", "noise")


def grid_xy(size, cells) -> tuple[np.ndarray, np.ndarray]:
    """Vertex coordinates of the grid: x, y of shape (ny + 1, nx + 1)."""
    sx, sy = float(size[0]), float(size[1])
    nx, ny = int(cells[0]), int(cells[1])
    xs = np.linspace(-sx / 2.0, sx / 2.0, nx + 1)
    ys = np.linspace(-sy / 2.0, sy / 2.0, ny + 1)
    return np.meshgrid(xs, ys, indexing="xy")


def grid_triangles(cells) -> np.ndarray:
    """Triangles of an (nx, ny)-cell grid, shape (2 nx ny, 3), counter-clockwise from +z."""
    nx, ny = int(cells[0]), int(cells[1])
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="xy")
    v00 = (j * (nx + 1) + i).ravel()
    v10 = v00 + 1
    v01 = v00 + (nx + 1)
    v11 = v01 + 1
    tris = np.empty((nx * ny, 2, 3), dtype=np.int64)
    tris[:, 0] = np.stack([v00, v10, v11], axis=1)
    tris[:, 1] = np.stack([v00, v11, v01], axis=1)
    return tris.reshape(-1, 3)


def sines_heights(x, y, amplitude: float, frequency) -> np.ndarray:
    fx, fy = float(frequency[0]), float(frequency[1])
    return amplitude * np.sin(fx * x) * np.cos(fy * y)


def noise_heights(shape, amplitude: float, seed: int, smoothing: int) -> np.ndarray:
    z = np.random.default_rng(seed).uniform(-1.0, 1.0, size=shape)
    for _ in range(smoothing):
        p = np.pad(z, 1, mode="edge")
        z = sum(p[1 + dj : 1 + dj + shape[0], 1 + di : 1 + di + shape[1]] for dj in (-1, 0, 1) for di in (-1, 0, 1)) / 9.0
    peak = float(np.abs(z).max())
    return z * (amplitude / peak) if peak > 0 else z


def heightfield(function: str, *, size, cells, amplitude: float, frequency=(1.0, 1.0), seed: int = 0,
                smoothing: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) and triangles (T, 3) of a height field centred on the origin."""
    x, y = grid_xy(size, cells)
    if function == "sines":
        z = sines_heights(x, y, amplitude, frequency)
    elif function == "noise":
        z = noise_heights(x.shape, amplitude, seed, smoothing)
    else:
        raise ValueError(f"unknown height-field function {function!r}; expected one of {FUNCTIONS}")
    vertices = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    return vertices, grid_triangles(cells)
