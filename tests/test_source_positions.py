"""The start-up shortcuts of sandbox/source_positions.py give Taichi the strings it would have
made itself (they end up in its IR and its error messages)."""

import textwrap
from pathlib import Path

from hypothesis import given, settings
from hypothesis import strategies as st

from sandbox.source_positions import _FittingLineWrapper

SOURCES = sorted((Path(__file__).resolve().parents[1] / "sandbox").rglob("*.py"))


def _both(text: str):
    return _FittingLineWrapper(width=80).wrap(text), textwrap.TextWrapper(width=80).wrap(text)


def test_every_engine_source_line_and_its_underlines_wrap_as_textwrap_does():
    """What get_pos_info wraps: each source line, and underlines of its spans padded to its length."""
    checked = 0
    for path in SOURCES:
        for line in path.read_text().splitlines():
            stripped = len(line) - len(line.lstrip())
            hints = ["", " " * stripped + "^" * (len(line) - stripped), "^" * len(line), " " * len(line)]
            for hint in hints:
                hint += " " * (len(line) - len(hint))
                for text in (line, hint):
                    ours, theirs = _both(text)
                    assert ours == theirs, (path.name, text)
                    checked += 1
    assert checked > 10_000


def test_edge_cases_wrap_as_textwrap_does():
    for text in ["", " ", "   x", "x   ", "  x  y  ", "a" * 80, "a" * 81, " " * 80 + "x", "a-b c--d e",
                 "\tindented", "x\ny", "x\x0cy", "caf\u00e9 ", "\u3000", "x\u3000", " " * 81]:
        ours, theirs = _both(text)
        assert ours == theirs, repr(text)


@settings(max_examples=400, deadline=None)
@given(st.text(alphabet=st.sampled_from(list(" \t\n-^_.()[]:,=+*/#\"'abcXYZ019\u00e9\u3000")), max_size=100))
def test_any_line_wraps_as_textwrap_does(text):
    ours, theirs = _both(text)
    assert ours == theirs
