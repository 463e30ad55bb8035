"""Drawing snapshots in a viser scene: one batched (instanced) node per distinct shape, all
poses of a frame sent in one atomic update, static geometry sent once per world."""

from __future__ import annotations

import numpy as np

from .shapes import body_shape, shape_mesh, static_meshes

SELECTED = np.array([255, 128, 0], dtype=np.uint8)
STATIC = np.array([170, 165, 160], dtype=np.uint8)
PALETTE = np.array([
    [76, 120, 168], [84, 162, 75], [228, 87, 86], [114, 183, 178], [238, 202, 59],
    [178, 121, 162], [255, 157, 166], [157, 117, 93], [186, 176, 172], [245, 133, 24],
], dtype=np.uint8)
COLOR_MODES = ("shape", "speed")
SPEED_RANGE = (-5.0, 1.0)  # log10 |v| [m/s] mapped from blue (at rest) to red (moving): 1e-4 m/s of jitter shows
ARROW = np.array([255, 0, 200], dtype=np.uint8)  # an inspected step's impulse arrows: magenta
ARROW_LENGTH = 0.8  # [m] the arrow of the largest normal impulse; others by the cube root of their share,
#                     so a light body's impulse under a heavy one's still shows
INSPECTED_OPACITY = 0.3  # bodies while a step is inspected: the arrows inside them show through
RESIDUAL_RANGE = (-6.0, 0.0)  # log10 residual [m/s] of an inspected point, from green (solved) to red
ASLEEP_SHADE = 0.45  # a sleeping body's colour is scaled by this: dimmed, its hue kept


class _Batch:
    def __init__(self, handle, indices: np.ndarray):
        self.handle = handle
        self.indices = indices


class WorldView:
    """Keeps a viser scene in step with the simulation's snapshots."""

    def __init__(self, server, on_pick=None, root: str = ""):
        self.server = server
        self.on_pick = on_pick  # callable(body index)
        self.root = root  # scene-tree prefix: "" for the world, "/twin" for the compare view's second
        self._world_id = None
        self._generation = None
        self._batches: dict[tuple, _Batch] = {}
        self._meshes: dict[tuple, tuple] = {}  # key -> (vertices, faces): a hull's mesh is built once per world
        self._colors_key = None
        self._contacts_shown = False
        self._inspection_shown = False
        self._base_colors = np.zeros((0, 3), dtype=np.uint8)
        self._static_mask = np.zeros(0, dtype=bool)

    def clear(self) -> None:
        """Take everything this view drew out of the scene (the compare view switched off)."""
        self.server.scene.remove_by_name(self.root or "/bodies")
        for batch in self._batches.values():
            batch.handle.remove()
        self._batches.clear()
        self._world_id = self._generation = None

    def show(self, snap, selected: int | None = None, color_mode: str = "shape") -> None:
        with self.server.atomic():
            if snap.world_id != self._world_id:
                self._new_world(snap)
            if snap.generation != self._generation:
                self._regroup(snap)
            colors = self._colors(snap, selected, color_mode)
            for batch in self._batches.values():
                idx = batch.indices
                batch.handle.batched_positions = snap.positions[idx]
                batch.handle.batched_wxyzs = snap.orientations[idx]
                if colors is not None:
                    batch.handle.batched_colors = colors[idx]
            self._show_contacts(snap.contacts)
            self._show_inspection(snap.inspection)

    # ------------------------------------------------------------------ structure
    def _new_world(self, snap) -> None:
        self.server.scene.remove_by_name(f"{self.root}/static")
        lo, hi = _bounds(snap.positions)
        half = float(max(20.0, 2.0 * np.max(hi - lo)))
        for name, verts, faces, color in static_meshes(snap.scene, half):
            self.server.scene.add_mesh_simple(self.root + name, np.asarray(verts, dtype=np.float32),
                                              np.asarray(faces, dtype=np.uint32), color=color,
                                              flat_shading=True, cast_shadow=False, receive_shadow=False)
        self._world_id = snap.world_id
        self._generation = None
        self._meshes.clear()

    def _regroup(self, snap) -> None:
        groups: dict[tuple, list[int]] = {}
        scales: list[np.ndarray] = []
        for i, body in enumerate(snap.bodies):
            key, scale = body_shape(body)
            groups.setdefault(key, []).append(i)
            scales.append(scale)
        scales = np.asarray(scales, dtype=np.float32).reshape(-1, 3)
        for key in list(self._batches):
            if key not in groups:
                self._batches.pop(key).handle.remove()
                self._meshes.pop(key, None)  # removed or fractured hulls do not come back
        for n, (key, members) in enumerate(sorted(groups.items(), key=lambda kv: kv[1][0])):
            idx = np.asarray(members, dtype=np.int64)
            if key not in self._meshes:
                self._meshes[key] = shape_mesh(key, snap.bodies[members[0]])
            vertices, faces = self._meshes[key]
            handle = self.server.scene.add_batched_meshes_simple(
                f"{self.root}/bodies/{_node_name(key)}", vertices, faces,
                batched_wxyzs=snap.orientations[idx], batched_positions=snap.positions[idx],
                batched_scales=scales[idx], batched_colors=np.zeros((len(idx), 3), dtype=np.uint8),
                flat_shading=key[0] != "sphere", cast_shadow=False, receive_shadow=False)
            batch = _Batch(handle, idx)
            if self.on_pick is not None:
                handle.on_click(self._picker(batch))
            self._batches[key] = batch
        count = len(snap.bodies)
        self._static_mask = np.array([b.static for b in snap.bodies], dtype=bool).reshape(count)
        self._base_colors = PALETTE[(np.arange(count) * 7919 + 13) % len(PALETTE)]
        self._base_colors[self._static_mask] = STATIC
        self._generation = snap.generation
        self._colors_key = None

    def _picker(self, batch: _Batch):
        def pick(event) -> None:
            k = event.instance_index
            if k is not None and 0 <= k < len(batch.indices):  # the first click can carry None
                self.on_pick(int(batch.indices[k]))
        return pick

    # ------------------------------------------------------------------ per frame
    def _colors(self, snap, selected, mode) -> np.ndarray | None:
        """Per-body colours, or None when nothing changed since the last frame."""
        asleep = snap.asleep
        key = (snap.generation, selected, mode, asleep.tobytes() if asleep.any() else b"")
        if mode == "shape" and key == self._colors_key:
            return None
        self._colors_key = key
        if mode == "speed":
            t = (np.log10(np.maximum(snap.speeds, 1e-9)) - SPEED_RANGE[0]) / (SPEED_RANGE[1] - SPEED_RANGE[0])
            t = np.clip(t, 0.0, 1.0)[:, None]
            colors = ((1.0 - t) * np.array([40, 90, 200]) + t * np.array([230, 40, 30])).astype(np.uint8)
            colors[self._static_mask] = STATIC
        else:
            colors = self._base_colors.copy()
        if len(asleep) == len(colors):
            colors[asleep] = (colors[asleep] * ASLEEP_SHADE).astype(np.uint8)
        if selected is not None and 0 <= selected < len(colors):
            colors[selected] = SELECTED
        return colors

    def _show_contacts(self, contacts) -> None:
        if contacts is None:
            if self._contacts_shown:
                self.server.scene.remove_by_name(f"{self.root}/contacts")
                self._contacts_shown = False
            return
        p, n = contacts["point"], contacts["normal"]
        if len(p) == 0:
            p, n = np.zeros((1, 3), np.float32), np.zeros((1, 3), np.float32)
        self.server.scene.add_point_cloud(f"{self.root}/contacts/points", p, colors=(255, 30, 30), point_size=0.05,
                                          point_shape="circle")
        segments = np.stack([p, p + 0.3 * n], axis=1)
        self.server.scene.add_line_segments(f"{self.root}/contacts/normals", segments, colors=(255, 220, 0), thickness=2.0,
                                            thickness_units="screen")
        self._contacts_shown = True


    def _show_inspection(self, inspection) -> None:
        """A paused step's contacts: each point coloured by its residual, an arrow along its normal
        growing with its normal impulse (the largest ARROW_LENGTH long)."""
        self._set_opacity(None if inspection is None else INSPECTED_OPACITY)
        if inspection is None:
            if self._inspection_shown:
                self.server.scene.remove_by_name(f"{self.root}/inspection")
                self._inspection_shown = False
            return
        c = inspection["contacts"]
        p, n = c["point"].astype(np.float32), c["normal"].astype(np.float32)
        if len(p) == 0:
            p, n = np.zeros((1, 3), np.float32), np.zeros((1, 3), np.float32)
            impulse, residual = np.zeros(1), np.zeros(1)
        else:
            impulse, residual = c["impulse"], c["residual"]
        t = (np.log10(np.maximum(residual, 1e-12)) - RESIDUAL_RANGE[0]) / (RESIDUAL_RANGE[1] - RESIDUAL_RANGE[0])
        t = np.clip(t, 0.0, 1.0)[:, None]
        colors = ((1.0 - t) * np.array([40, 200, 60]) + t * np.array([230, 30, 30])).astype(np.uint8)
        self.server.scene.add_point_cloud(f"{self.root}/inspection/points", p, colors=colors, point_size=0.08,
                                          point_shape="circle")
        length = ARROW_LENGTH * np.cbrt(impulse / max(float(impulse.max()), 1e-12))
        segments = np.stack([p, p + n * length[:, None].astype(np.float32)], axis=1)
        self.server.scene.add_line_segments(f"{self.root}/inspection/impulses", segments, colors=tuple(int(x) for x in ARROW),
                                            thickness=4.0, thickness_units="screen")
        self._inspection_shown = True


    def _set_opacity(self, opacity: float | None) -> None:
        for batch in self._batches.values():
            if batch.handle.opacity != opacity:
                batch.handle.opacity = opacity


def configure_lighting(scene) -> None:
    """Fast in a software-rendered browser (apis.md: the environment map and the shadowed
    default lights cost ~1 FPS there): no environment map, no default lights, no shadows."""
    scene.configure_environment_map(None)
    scene.configure_default_lights(enabled=False)
    scene.add_light_ambient("/lights/ambient", intensity=0.55)
    scene.add_light_directional("/lights/sun", intensity=1.6, position=(6.0, -10.0, 14.0))


def _node_name(key: tuple) -> str:
    return "_".join(str(k).replace(".", "p") for k in key)


def _bounds(positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    if len(positions) == 0:
        return np.zeros(3), np.ones(3)
    return positions.min(axis=0), positions.max(axis=0)


PANEL_SHIFT = 0.45
"""How far right of the bodies' centre the camera looks, in bounding radii, so the bodies sit
in the left part of the view that the control panel (docked on the right) leaves free."""


def camera_for(positions: np.ndarray) -> tuple[tuple, tuple]:
    """(position, look_at) that frames the bodies from the front, slightly above, in the part of
    the view left of the panel. The camera looks along +y, so its right is +x."""
    lo, hi = _bounds(positions)
    centre = 0.5 * (lo + hi)
    radius = float(max(2.0, 0.6 * np.linalg.norm(hi - lo)))
    target = centre + np.array([PANEL_SHIFT * radius, 0.0, 0.0])
    eye = target + radius * np.array([0.35, -1.7, 0.75])
    return tuple(float(x) for x in eye), tuple(float(x) for x in target)
