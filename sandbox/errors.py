"""The sandbox's own exception types.

Every failure a user can cause (a bad scene file, a bad API argument, a step that
blows up) surfaces as a :class:`SandboxError` subclass with one sentence naming
where the problem is and what it is, never as a raw Taichi or numpy traceback.
"""

from __future__ import annotations


class SandboxError(Exception):
    """Base class of every error raised on purpose by the sandbox."""


class SceneError(SandboxError, ValueError):
    """A scene (file or dict) is invalid.

    The message always names the source (file path or ``<dict>``), the entry
    (e.g. ``body[3].half_extents``) and the problem.
    """

    def __init__(self, problem: str, *, source: str | None = None, entry: str | None = None):
        self.problem = problem
        self.source = source
        self.entry = entry
        where = []
        if source:
            where.append(f"scene {source}")
        if entry:
            where.append(f"entry {entry}")
        prefix = ": ".join(where)
        super().__init__(f"{prefix}: {problem}" if prefix else problem)


class SimulationError(SandboxError, RuntimeError):
    """A step could not complete (non-finite state, a buffer over capacity).

    The world keeps the last good state when this is raised.
    """


class CapacityError(SimulationError):
    """A fixed-capacity buffer overflowed and could not be grown automatically."""
