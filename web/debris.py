"""Random debris for the "Drop debris" button: the scene generators' ``rain``, in a region
above whatever is already in the world, so new bodies never start inside old ones."""

from __future__ import annotations

import numpy as np

from sandbox import GeneratorError, Material, SandboxError, rain

DEBRIS_MIXES = ("mixed", "boxes", "spheres", "hulls", "capsules")
_SHAPES = {
    "mixed": (("box", "sphere", "hull", "capsule"), (0.4, 0.2, 0.3, 0.1)),
    "boxes": (("box",), None),
    "spheres": (("sphere",), None),
    "hulls": (("hull",), None),
    "capsules": (("capsule",), None),
}
DEBRIS_KINDS = tuple(sorted({kind for shapes, _ in _SHAPES.values() for kind in shapes}))
"""Every shape kind a drop can bring: a web world compiles its collision for them from the start."""
MAX_DEBRIS = 200
"""Most bodies one drop adds (the panel's slider); a web world reserves room for one such drop."""
HALF_SIZE_RANGE = (0.15, 0.45)  # [m]
CLEARANCE = 1.0  # [m] between the highest body and the bottom of the drop region
MAX_LAYERS = 64


def debris_bodies(snap, count: int, mix: str, seed: int) -> list:
    """``count`` bodies of the ``mix`` above the bodies of ``snap``, seeded."""
    if mix not in _SHAPES:
        raise SandboxError(f"unknown debris mix {mix!r}; choose one of {', '.join(DEBRIS_MIXES)}")
    shapes, weights = _SHAPES[mix]
    dynamic = np.array([not b.static for b in snap.bodies], dtype=bool)
    pos = snap.positions[dynamic] if dynamic.any() else snap.positions
    if len(pos):
        lo, hi = pos.min(axis=0), pos.max(axis=0)
    else:
        lo, hi = np.array([-1.0, -1.0, 0.0]), np.array([1.0, 1.0, 0.0])
    centre = 0.5 * (lo[:2] + hi[:2])
    half = np.maximum(0.5 * (hi[:2] - lo[:2]), 1.5)  # at least a 3 x 3 m footprint
    bottom = hi[2] + CLEARANCE + 2.0 * HALF_SIZE_RANGE[1]
    cell = 2.0 * np.sqrt(3.0) * HALF_SIZE_RANGE[1]  # the widest body's world extent
    per_layer = max(1, int((2 * half[0]) // cell) * int((2 * half[1]) // cell))
    layers = min(MAX_LAYERS, int(np.ceil(count / per_layer)) + 1)
    low = np.array([centre[0] - half[0], centre[1] - half[1], bottom])
    high = np.array([centre[0] + half[0], centre[1] + half[1], bottom + layers * cell])
    try:
        return rain(count, low, high, shapes=shapes, weights=weights, half_extent_range=HALF_SIZE_RANGE,
                    seed=seed, material=Material(density=1000.0))
    except GeneratorError as exc:
        raise SandboxError(f"cannot place {count} debris bodies above the pile: {exc}") from None
