"""The shipped scene library: ``scenes/*.toml`` beside the package, found by file or by name."""

from __future__ import annotations

from pathlib import Path

from ..errors import SandboxError

SCENES_DIR = Path(__file__).resolve().parent.parent.parent / "scenes"


def shipped_scenes() -> list[Path]:
    """Every shipped scene file, sorted by name."""
    return sorted(SCENES_DIR.glob("*.toml"))


def resolve_scene(name: str | Path) -> Path:
    """A scene file path, or the name of a shipped scene (``pyramid_20`` or ``pyramid_20.toml``)."""
    p = Path(name)
    if p.is_file():
        return p
    for candidate in (SCENES_DIR / str(name), SCENES_DIR / f"{name}.toml"):
        if candidate.is_file():
            return candidate
    known = ", ".join(q.stem for q in shipped_scenes())
    raise SandboxError(f"no scene file {str(name)!r} (and no shipped scene of that name; shipped: {known})")
