"""A look inside one solve: a step run one sweep at a time (``World.inspect_step``).

Between two sweeps the solver's state is what a student wants to see: each contact point's
accumulated normal impulse and how far its rows are from being solved (the residual), the
RMS residual after every sweep so far, and, for the Jacobi family, the velocities of a body's
sub-bodies: every block solved its rows on its own copy of the body (mass splitting: one of
mass m / n_b per block), and the sweep merged them into one velocity, their (possibly
over-relaxed) average. The step runs stage by stage (step.py), which gives the same bits as
``World.step``; reading the state between sweeps changes nothing.
"""

from __future__ import annotations

import numpy as np

from .errors import SandboxError
from .lanes import LANES


class StepInspection:
    """One step of ``world``, paused after each sweep. ``advance()`` runs to the next sweep's
    end and returns its ``step.Sweep`` (None once the step is over); ``finish()`` runs the rest."""

    def __init__(self, world, sweeps):
        self.world = world
        self._sweeps = sweeps
        self.sweep = None  # the step.Sweep just run; None before the first and after the last
        self.residuals: list[float] = []  # [m/s] RMS residual after each sweep so far
        self.done = False

    def advance(self):
        if self.done:
            return None
        try:
            self.sweep = next(self._sweeps)
        except StopIteration:
            self._close()
            return None
        except BaseException:
            self._close()
            raise
        self.residuals.append(self._residual_rms())
        return self.sweep

    def finish(self) -> None:
        while self.advance() is not None:
            pass

    def _close(self) -> None:
        self.done = True
        self.sweep = None
        self.world._inspection = None

    # ------------------------------------------------------------------ what a pause shows
    def contacts(self) -> dict[str, np.ndarray]:
        """This step's contact points: point, normal (a to b), normal impulse accumulated in this
        substep [N s], residual [m/s] of the point's rows in the problem the last sweep solved."""
        self._require_pause()
        b = self.world.buf
        n = int(b.contacts.count[None])
        self._compute_residuals()
        return {
            "point": b.contacts.point.to_numpy()[:n],
            "normal": b.contacts.normal.to_numpy()[:n],
            "impulse": b.rows.lam.to_numpy()[:n, 0],
            "residual": np.sqrt(np.maximum(b.rows.residual.to_numpy()[:n], 0.0)),
        }

    def sub_bodies(self, body: int) -> dict | None:
        """Body ``body``'s sub-body velocities after the last sweep, one per block touching it
        (rows "linear" and "angular", (k, 3)), the blocks' contact points or manifolds
        ("blocks") and whether each counts in n_b ("counted"; the others are idle, split apart:
        Settings.idle_split), the velocity before the sweep ("before") and the merged one
        ("merged": the average of the sub-bodies, over-relaxed by the schedule's omega), and the
        counted blocks' split ("split"). None for the PGS
        solvers, which have no sub-bodies (every row acts on the body itself, in turn). A relax
        sweep that carries the next substep's warm start has it in its sub-bodies too."""
        self._require_pause()
        if self.world._schedule.info.visit != "blocks":
            return None
        body = self.world._edits.check_indices([body], "inspect", dynamic=True)[0]
        s = self.world.buf.blocks
        start, end = int(s.adj_start[body]), int(s.adj_start[body + 1])
        slots = s.adj.to_numpy()[start:end]
        blocks = slots // 2
        counted = self._block_counted(blocks)
        weight = np.where(counted, float(s.weight[body]), 1.0 / float(s.scale_idle[body]))[:, None]
        side, group, lane = slots % 2, blocks // LANES, blocks % LANES  # block_adjacency.slot_change
        changes = s.slots.to_numpy()[side, group, :, lane]  # [side, group][row, lane]
        dv, dw = changes[:, :3], changes[:, 3:]
        st = self.world.buf.bodies.state_numpy(("linear_velocity", "angular_velocity"))
        v1, w1 = st["linear_velocity"][body], st["angular_velocity"][body]
        gravity = np.zeros(3)
        if self.sweep.carries_warm_start:  # the merge also added the next substep's gravity
            gravity = self.world.gravity * self.world.dt / (self.world.substeps * self.sweep.substeps)
        v0, w0 = v1 - dv.sum(axis=0) - gravity, w1 - dw.sum(axis=0)  # the velocity the sweep started from
        return {
            "blocks": blocks,
            "counted": counted,
            "linear": v0 + dv / weight,
            "angular": w0 + dw / weight,
            "before": (v0, w0),
            "merged": (v1, w1),
            "split": float(s.scale[body]),
        }

    def _block_counted(self, blocks: np.ndarray) -> np.ndarray:
        """Whether each block counts in its bodies' n_b (rows.counted of its first point)."""
        c = self.world.buf.contacts
        first = blocks
        if self.world._schedule.info.block == "manifold":
            first = c.m_start.to_numpy()[blocks]
        return self.world.buf.rows.counted.to_numpy()[first].astype(bool)

    # ------------------------------------------------------------------ helpers
    def _require_pause(self) -> None:
        if self.sweep is None:
            raise SandboxError("the inspected step is not paused after a sweep (advance() first; it ends "
                               "after the last)")

    @property
    def mode(self) -> int:
        """The problem the last sweep solved: rows.BIASED or rows.RELAX (RELAX when not paused)."""
        from .solvers.rows import BIASED, RELAX

        return BIASED if self.sweep is not None and self.sweep.phase in ("biased", "extra biased") else RELAX

    def _compute_residuals(self) -> None:
        from .solvers.rows import compute_residuals

        b = self.world.buf
        compute_residuals(b.rows, b.contacts, b.bodies, self.mode)

    def _residual_rms(self) -> float:
        from .step import residual_rms

        return residual_rms(self.world.buf, self.mode)
