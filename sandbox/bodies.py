"""Rigid bodies in Taichi fields, split by who reads them (house rule 2).

* info (fixed per body): inverse mass, body-frame inertia and its inverse;
* state (changes every step): centre-of-mass position, orientation (w, x, y, z),
  linear and angular velocity (world frame);
* position remainder: the part of the position a float32 cannot hold, so that
  ``pos + pos_rem`` is the position to ~48 bits. At 15 m a float32 step is 1 um,
  while a resting box moves ~1e-7 m per substep: plain float32 sums round that
  motion away, the pile freezes against springs still pushing it, and the solver
  keeps a velocity floor that only looks like jitter (measured on the 210-box
  pyramid: 1e-4 J of kinetic energy that was rounding, docs/method-notes.md);
* motion since the step began (``moved``), summed from the substeps' updates: derivable
  from the two position pairs, but kept because the relax sweep's separation update reads
  it for every contact point (one vector instead of four) and, being small, float32 holds
  it to full precision;
* derived per step: world inverse inertia, read by the solver's inner loop;
* last good state: a device-side copy taken at the start of every step, restored
  when a step produces non-finite numbers (the world keeps its last good state); it holds
  the support loads too, which the step's end updates from its impulses (a diverged step's
  would stiffen the next step's springs by loads no good state had).

Static bodies have inverse mass and inverse inertia zero and are never moved.
"""


import numpy as np
import taichi as ti

from .awake import EVERY, body_id, body_total
from .backend import serialize_light_loops
from .field_upload import write_rows
from .math3d import mat_mul, quat_to_mat

vec3 = ti.math.vec3


@ti.data_oriented
class Bodies:
    def __init__(self, capacity: int):
        self.capacity = capacity
        c = capacity
        self.count = ti.field(ti.i32, ())
        self.inv_mass = ti.field(ti.f32, c)
        self.inertia = ti.Matrix.field(3, 3, ti.f32, c)
        self.inv_inertia = ti.Matrix.field(3, 3, ti.f32, c)
        self.pos = ti.Vector.field(3, ti.f32, c)
        self.rot = ti.Vector.field(4, ti.f32, c)
        self.lin_vel = ti.Vector.field(3, ti.f32, c)
        self.ang_vel = ti.Vector.field(3, ti.f32, c)
        self.inv_inertia_world = ti.Matrix.field(3, 3, ti.f32, c)
        self.pos_rem = ti.Vector.field(3, ti.f32, c)
        self.moved = ti.Vector.field(3, ti.f32, c)
        self.good_pos = ti.Vector.field(3, ti.f32, c)
        self.good_pos_rem = ti.Vector.field(3, ti.f32, c)
        self.good_rot = ti.Vector.field(4, ti.f32, c)
        self.good_lin_vel = ti.Vector.field(3, ti.f32, c)
        self.good_ang_vel = ti.Vector.field(3, ti.f32, c)
        self.support = ti.field(ti.f32, c)  # [N] averaged force holding the body up (contact_spring.py)
        self.support_slow = ti.field(ti.f32, c)  # [N] the same, followed more slowly, for the preload (contact_preload_lag)
        self.support_points = ti.field(ti.i32, c)  # contact points holding it up, last step
        self.good_support = ti.field(ti.f32, c)
        self.good_support_slow = ti.field(ti.f32, c)
        self.good_support_points = ti.field(ti.i32, c)
        self.damping = ti.Vector.field(2, ti.f32, c)  # [1/s] linear, angular (scene.spec.RESISTANCE_KEYS)
        self.rolling = ti.Vector.field(2, ti.f32, c)  # [m] rolling, torsional friction lever arms
        self.placed = ti.field(ti.i32, c)  # 1: put in the world since the last narrowphase (mark_placed)

    def upload(self, arrays: dict[str, np.ndarray]) -> None:
        """Write host arrays (N rows each) into the first N slots (``upload_columns``), then
        derive what follows from them (``finish_upload``)."""
        write_rows(self.upload_columns(arrays))
        self.finish_upload(len(arrays["inv_mass"]))

    def upload_columns(self, arrays: dict[str, np.ndarray]) -> list:
        """``upload``'s rows as field_upload.write_rows columns, for a caller that writes them
        with other buffers' in one launch (build.upload). Dynamic bodies keep their float64
        positions exactly (float32 value plus remainder); static ones sit at the float32 value,
        where their geometry is. Every body's support loads start at zero: a new world learns its
        loads (a few steps); an edit carries them (edits.py)."""
        n = len(arrays["inv_mass"])
        if n > self.capacity:
            raise ValueError("body capacity exceeded")
        pos64 = np.asarray(arrays["pos"], dtype=np.float64)
        columns = {name: arrays[name] for name in ("inv_mass", "inertia", "inv_inertia", "pos", "rot", "lin_vel",
                                                   "ang_vel")}
        for name in ("damping", "rolling"):  # motion resistances: none unless given (scene.spec.RESISTANCE_KEYS)
            columns[name] = arrays.get(name, np.zeros((n, 2)))
        columns["pos_rem"] = (pos64 - pos64.astype(np.float32)) * (np.asarray(arrays["inv_mass"]) > 0)[:, None]
        rows = [(getattr(self, name), 0, np.asarray(value, np.float64)) for name, value in columns.items()]
        return rows + [(getattr(self, name), 0, np.zeros(self.capacity)) for name in self.LOAD_FIELDS]

    def finish_upload(self, n: int) -> None:
        """After ``upload_columns``' rows are written: the body count, the world-frame inertias and
        the first good state."""
        self.count[None] = n
        update_world_inertia(self, EVERY)
        save_good_state(self, EVERY)

    LOAD_FIELDS = ("support", "support_slow", "support_points")

    def read_loads(self, n: int) -> dict[str, np.ndarray]:
        """The first n bodies' support loads (contact_spring.py), to carry across a rebuild."""
        return {name: getattr(self, name).to_numpy()[:n] for name in self.LOAD_FIELDS}

    def write_loads(self, loads: dict[str, np.ndarray], body_map: np.ndarray) -> None:
        """``read_loads``'s arrays again, old body i as body ``body_map[i]`` (-1: gone), into a
        world just uploaded (whose loads are zero) and into its good state, in one launch."""
        kept = body_map >= 0
        n = int(self.count[None])
        columns = []
        for name, old in loads.items():
            new = np.zeros((n,) + old.shape[1:], old.dtype)
            new[body_map[kept]] = old[kept]
            columns += [(getattr(self, name), 0, new), (getattr(self, "good_" + name), 0, new)]
        write_rows(columns)

    def mark_placed(self, indices: np.ndarray) -> None:
        """Flag the bodies put in the world (by the scene, an edit or a fracture) that no
        narrowphase has seen yet: a pair of theirs found deeper than a resting contact is an
        overlap to push out gently (manifold_cache.carry_overlap), not an impact."""
        write_rows(self.placed_columns(indices))

    def placed_columns(self, indices: np.ndarray) -> list:
        """``mark_placed``'s flags as a write_rows column (every slot: the others cleared)."""
        flags = np.zeros(self.capacity, np.int32)
        flags[np.asarray(indices, np.int64)] = 1
        return [(self.placed, 0, flags)]

    STATE_FIELDS = {"position": "pos", "orientation": "rot", "linear_velocity": "lin_vel",
                    "angular_velocity": "ang_vel"}

    def state_numpy(self, fields=None) -> dict[str, np.ndarray]:
        """``fields``: the STATE_FIELDS keys to copy off the device (default all)."""
        n = int(self.count[None])
        return {k: getattr(self, self.STATE_FIELDS[k]).to_numpy()[:n] for k in (fields or self.STATE_FIELDS)}

    def exact_positions(self) -> np.ndarray:
        """Positions with their remainders, float64 (N, 3)."""
        n = int(self.count[None])
        return self.pos.to_numpy()[:n].astype(np.float64) + self.pos_rem.to_numpy()[:n]

    def host_state(self) -> dict[str, np.ndarray]:
        """The state under ``upload``'s names, float64, positions exact: what a rebuild
        uploads again, so that it loses nothing."""
        n = int(self.count[None])
        state = {k: getattr(self, k).to_numpy()[:n].astype(np.float64) for k in ("rot", "lin_vel", "ang_vel")}
        state["pos"] = self.exact_positions()
        return state


@ti.func
def update_body_inertia(b: ti.template(), i: ti.i32):
    r = quat_to_mat(b.rot[i])
    b.inv_inertia_world[i] = mat_mul(mat_mul(r, b.inv_inertia[i]), r.transpose())


@ti.func
def update_world_inertia_loops(b: ti.template(), awake: ti.template()):
    """``awake`` (awake.py): every body, or the awake ones (a sleeping body keeps the world
    inertia of the pose it fell asleep in)."""
    n = body_total(b, awake)
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(n):
        update_body_inertia(b, body_id(awake, k))


@ti.kernel
def update_world_inertia(b: ti.template(), awake: ti.template()):
    update_world_inertia_loops(b, awake)


@ti.func
def save_body_state(b: ti.template(), i: ti.i32):
    b.good_pos[i] = b.pos[i]
    b.good_pos_rem[i] = b.pos_rem[i]
    b.moved[i] = vec3(0.0)
    b.good_rot[i] = b.rot[i]
    b.good_lin_vel[i] = b.lin_vel[i]
    b.good_ang_vel[i] = b.ang_vel[i]
    b.good_support[i] = b.support[i]
    b.good_support_slow[i] = b.support_slow[i]
    b.good_support_points[i] = b.support_points[i]


@ti.func
def save_good_state_loops(b: ti.template(), awake: ti.template()):
    """A sleeping body's good state is the pose it fell asleep in (sleep.py saves it then)."""
    n = body_total(b, awake)
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(n):
        save_body_state(b, body_id(awake, k))


@ti.kernel
def save_good_state(b: ti.template(), awake: ti.template()):
    save_good_state_loops(b, awake)


@ti.kernel
def restore_good_state(b: ti.template()):
    for i in range(b.count[None]):
        b.pos[i] = b.good_pos[i]
        b.pos_rem[i] = b.good_pos_rem[i]
        b.moved[i] = vec3(0.0)
        b.rot[i] = b.good_rot[i]
        b.lin_vel[i] = b.good_lin_vel[i]
        b.ang_vel[i] = b.good_ang_vel[i]
        b.support[i] = b.good_support[i]
        b.support_slow[i] = b.good_support_slow[i]
        b.support_points[i] = b.good_support_points[i]
