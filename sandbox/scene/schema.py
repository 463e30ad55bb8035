"""Typed, strict reading of one scene table: keys, types, ranges, and the error sentence.

A ``Reader`` wraps one table of the scene (the top level, ``[world]``,
``body[3]``, ``body[3].parts[1]`` ...) and hands out validated values. Every
problem becomes a ``SceneError`` naming the source, the entry (``body[3].radius``)
and what is wrong; nothing else escapes (numbers that overflow a float, lists of
the wrong length or of strings, NaN and inf all end here).

The schema itself (which keys each table allows) lives in ``keys.py``; the
user-facing description of every key is ``scenes/README.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import SceneError

MISSING = object()


@dataclass
class Context:
    source: str
    base_dir: Path
    cache: dict = field(default_factory=dict)  # loaded mesh files by resolved path
    warnings: list = field(default_factory=list)  # repairs and fallbacks, one sentence each (Scene.warnings)


def _kind_of(value) -> str:
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, (int, np.integer)):
        return "an integer"
    if isinstance(value, (float, np.floating)):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, (list, tuple, np.ndarray)):
        return "a list"
    return type(value).__name__


def _show(value) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def is_number(value) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


class Reader:
    """Validated access to one table; ``entry`` is its path in the scene ('' for the top level)."""

    def __init__(self, data, entry: str, ctx: Context):
        self.entry = entry
        self.ctx = ctx
        if not isinstance(data, dict):
            raise SceneError(f"expected a table, got {_kind_of(data)} {_show(data)}", source=ctx.source, entry=entry or None)
        self.data = data

    # ------------------------------------------------------------------ helpers
    def at(self, key: str) -> str:
        return f"{self.entry}.{key}" if self.entry else key

    def error(self, problem: str, key: str | None = None) -> SceneError:
        return SceneError(problem, source=self.ctx.source, entry=self.at(key) if key else (self.entry or None))

    def has(self, key: str) -> bool:
        return key in self.data

    def check_keys(self, allowed, required=(), *, what: str = "") -> None:
        """Reject unknown keys (listing the allowed ones) and missing required keys."""
        allowed = list(allowed)
        for key in self.data:
            if not isinstance(key, str):
                raise self.error(f"keys must be strings, got {_show(key)}")
            if key not in allowed:
                label = f" for {what}" if what else ""
                raise self.error(f"unknown key '{key}'{label}; allowed keys: {', '.join(sorted(allowed))}", key)
        for key in required:
            if key not in self.data:
                label = f" ({what})" if what else ""
                raise self.error(f"missing required key '{key}'{label}", key)

    def exclusive(self, *keys: str, required: bool = True) -> str | None:
        """Exactly one (or, with required=False, at most one) of ``keys`` is present; returns it."""
        present = [k for k in keys if k in self.data]
        if len(present) > 1:
            raise self.error(f"give either '{present[0]}' or '{present[1]}', not both", present[1])
        if not present:
            if required:
                raise self.error(f"missing required key: one of {', '.join(repr(k) for k in keys)}", keys[0])
            return None
        return present[0]

    def _get(self, key, default):
        if key in self.data:
            return self.data[key], True
        if default is MISSING:
            raise self.error(f"missing required key '{key}'", key)
        return default, False

    # ------------------------------------------------------------------ scalars
    def number(self, value, key: str) -> float:
        if not is_number(value):
            raise self.error(f"expected a number, got {_kind_of(value)} {_show(value)}", key)
        try:
            x = float(value)
        except OverflowError:
            raise self.error(f"number {_show(value)} is too large", key) from None
        if not math.isfinite(x):
            raise self.error(f"expected a finite number, got {x}", key)
        return x

    def real(self, key, default=MISSING, *, positive=False, nonnegative=False, low=None, high=None,
              open_low=False, open_high=False) -> float:
        value, given = self._get(key, default)
        if not given:
            return value
        x = self.number(value, key)
        if positive and not x > 0:
            raise self.error(f"must be > 0, got {x}", key)
        if nonnegative and not x >= 0:
            raise self.error(f"must be >= 0, got {x}", key)
        if low is not None and (x < low or (open_low and x == low)):
            raise self.error(f"must be {'>' if open_low else '>='} {low}, got {x}", key)
        if high is not None and (x > high or (open_high and x == high)):
            raise self.error(f"must be {'<' if open_high else '<='} {high}, got {x}", key)
        return x

    def integer(self, key, default=MISSING, *, minimum=None, maximum=None) -> int:
        value, given = self._get(key, default)
        if not given:
            return value
        return self.integer_value(value, key, minimum=minimum, maximum=maximum)

    def integer_value(self, value, key, *, minimum=None, maximum=None) -> int:
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
            raise self.error(f"expected an integer, got {_kind_of(value)} {_show(value)}", key)
        n = int(value)
        if not -(2**63) <= n < 2**63:
            raise self.error(f"integer {_show(value)} is too large", key)
        if minimum is not None and n < minimum:
            raise self.error(f"must be >= {minimum}, got {n}", key)
        if maximum is not None and n > maximum:
            raise self.error(f"must be <= {maximum}, got {n}", key)
        return n

    def boolean(self, key, default=MISSING) -> bool:
        value, given = self._get(key, default)
        if not given:
            return value
        if not isinstance(value, (bool, np.bool_)):
            raise self.error(f"expected true or false, got {_kind_of(value)} {_show(value)}", key)
        return bool(value)

    def string(self, key, default=MISSING, *, choices=None, what="value") -> str:
        value, given = self._get(key, default)
        if not given:
            return value
        return self._choice(value, key, choices, what)

    def _choice(self, value, key, choices, what) -> str:
        """``value`` as a string that is one of ``choices`` (any string when choices is None)."""
        if not isinstance(value, str):
            raise self.error(f"expected a string, got {_kind_of(value)} {_show(value)}", key)
        if choices is not None and value not in choices:
            raise self.error(f"unknown {what} {value!r}; expected one of: {', '.join(choices)}", key)
        return value

    # ------------------------------------------------------------------ arrays
    def _list(self, value, key) -> list:
        if isinstance(value, np.ndarray):
            value = value.tolist()
        if not isinstance(value, (list, tuple)):
            raise self.error(f"expected a list, got {_kind_of(value)} {_show(value)}", key)
        return list(value)

    def vector(self, key, n: int, default=MISSING, *, positive=False, nonnegative=False, nonzero=False) -> np.ndarray:
        value, given = self._get(key, default)
        if not given:
            return None if value is None else np.array(value, dtype=np.float64)
        items = self._list(value, key)
        if len(items) != n:
            raise self.error(f"expected a list of {n} numbers, got {len(items)} items: {_show(value)}", key)
        v = np.array([self.number(x, key) for x in items], dtype=np.float64)
        if positive and not np.all(v > 0):
            raise self.error(f"every component must be > 0, got {v.tolist()}", key)
        if nonnegative and not np.all(v >= 0):
            raise self.error(f"every component must be >= 0, got {v.tolist()}", key)
        if nonzero and not np.linalg.norm(v) > 0:
            raise self.error(f"must not be the zero vector, got {v.tolist()}", key)
        if nonzero and not np.isfinite(np.linalg.norm(v)):
            raise self.error(f"vector is too long, got {v.tolist()}", key)
        return v

    def items(self, key) -> list:
        """A required list, as a Python list (its items unchecked)."""
        value, _ = self._get(key, MISSING)
        return self._list(value, key)

    def string_set(self, key, choices, *, what="value") -> tuple[str, ...]:
        """A list of distinct strings, each one of ``choices`` (may be empty); returned sorted."""
        out = []
        for i, item in enumerate(self.items(key)):
            if self._choice(item, f"{key}[{i}]", choices, what) in out:
                raise self.error(f"{what} {item!r} is listed twice", f"{key}[{i}]")
            out.append(item)
        return tuple(sorted(out))

    def scalar_or_vector(self, key, n: int, default=MISSING, *, positive=False) -> np.ndarray:
        """A number (used for every component) or a list of ``n`` numbers."""
        value, given = self._get(key, default)
        if not given:
            return None if value is None else np.broadcast_to(np.asarray(value, dtype=np.float64), (n,)).copy()
        if is_number(value):
            x = self.number(value, key)
            if positive and not x > 0:
                raise self.error(f"must be > 0, got {x}", key)
            return np.full(n, x)
        return self.vector(key, n, positive=positive)

    def choice_list(self, key, choices, *, what="value") -> list[str]:
        """A non-empty list of strings, each one of ``choices``."""
        value, _ = self._get(key, MISSING)
        items = self._list(value, key)
        if not items:
            raise self.error(f"expected a non-empty list of {what}s", key)
        return [self._choice(item, f"{key}[{i}]", choices, what) for i, item in enumerate(items)]

    def int_vector(self, key, n: int, default=MISSING, *, minimum=None, maximum=None) -> np.ndarray:
        value, given = self._get(key, default)
        if not given:
            return np.array(value, dtype=np.int64)
        items = self._list(value, key)
        if len(items) != n:
            raise self.error(f"expected a list of {n} integers, got {len(items)} items: {_show(value)}", key)
        return np.array([self.integer_value(x, key, minimum=minimum, maximum=maximum) for x in items], dtype=np.int64)

    def quaternion(self, key, default=(1.0, 0.0, 0.0, 0.0)) -> np.ndarray:
        """A (w, x, y, z) list, normalised; the zero quaternion is rejected."""
        q = self.vector(key, 4, default)
        norm = float(np.linalg.norm(q))
        if not norm > 1e-12:
            raise self.error(f"orientation quaternion (w, x, y, z) has zero length: {q.tolist()}", key)
        if not math.isfinite(norm):
            raise self.error(f"orientation quaternion is too long: {q.tolist()}", key)
        q = q / norm
        return -q if q[0] < 0 else q

    def points(self, key) -> np.ndarray:
        """A list of [x, y, z] points, shape (V, 3)."""
        value, _ = self._get(key, MISSING)
        items = self._list(value, key)
        if not items:
            raise self.error("expected a non-empty list of [x, y, z] points", key)
        out = np.empty((len(items), 3))
        for i, p in enumerate(items):
            row = self._list(p, f"{key}[{i}]")
            if len(row) != 3:
                raise self.error(f"expected a point [x, y, z], got {_show(p)}", f"{key}[{i}]")
            out[i] = [self.number(x, f"{key}[{i}]") for x in row]
        return out

    def file(self, key) -> Path:
        """A file path, relative ones resolved against the scene file's directory."""
        value = self.string(key)
        if not value:
            raise self.error("expected a file path, got an empty string", key)
        if "\x00" in value:
            raise self.error(f"invalid mesh file path {value!r}: it contains a NUL character", key)
        path = Path(value)
        if not path.is_absolute():
            path = self.ctx.base_dir / path
        try:
            exists, is_file = path.exists(), path.is_file()
        except (OSError, ValueError) as exc:  # e.g. an embedded NUL byte, a name too long
            raise self.error(f"invalid mesh file path {value!r}: {exc}", key) from None
        if not exists:
            raise self.error(f"mesh file not found: {path}", key)
        if not is_file:
            raise self.error(f"mesh path is not a file: {path}", key)
        return path

    # ------------------------------------------------------------------ nesting
    def table(self, key, default=MISSING) -> "Reader | None":
        value, given = self._get(key, default)
        if not given:
            return None if value is None else Reader(value, self.at(key), self.ctx)
        return Reader(value, self.at(key), self.ctx)

    def tables(self, key) -> list["Reader"]:
        """An array of tables (``[[body]]``); absent means empty."""
        if key not in self.data:
            return []
        items = self._list(self.data[key], key)
        return [Reader(item, f"{self.at(key)}[{i}]", self.ctx) for i, item in enumerate(items)]
