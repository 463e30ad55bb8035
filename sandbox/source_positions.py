"""Taichi's source-position strings, computed once per source position instead of once per visit.

Taichi 1.7 turns every kernel's Python AST into its IR at each process start, even when the
compiled kernel then comes from the offline cache (the cache key is taken from that IR). For
every statement and expression it visits it formats a "File ..., line ..." string with the
source line underlined, wrapped by ``textwrap`` (``ASTTransformerContext.get_pos_info``), and a
``ti.func`` is visited again at every call site: starting a world with a warm cache made ~89 000
such strings, 199 000 ``textwrap`` calls, a third of the AST time under cProfile. The string
depends only on the function's source (fixed by its file, its first line and its name within a
process), its indentation and the node's position, so it is memoised on exactly those; error
messages are the same strings as before.

The same start also read every ``ti.func``'s source again at every call site it was inlined
into (``kernel_impl._get_tree_and_ctx``: ``inspect.getsourcelines``, which tokenizes the
file's block, and a ``textwrap.fill`` per source line), ~0.4 s of a 20-box scene's 1.9 s first
step with a warm cache. ``memoise_function_sources`` keeps each function's source lines and
the fill / dedent results, which depend only on their inputs; the parse itself still runs per
call site, since the transformer writes into the tree. A side effect: a process keeps
compiling the sources it first read, even if a file changes on disk while it runs.

What is left of a position string, on a first visit, is mostly ``textwrap``'s line wrapping at
80 columns of the source line and of its underline (~28 000 ``wrap`` calls in a 20-box scene's
start; the strings took 0.36 s of it before, 0.21 s after, docs/bench.md "Eleventh pass"). A line that fits needs no wrapping: ``_FittingLineWrapper``
answers it directly, with the string ``TextWrapper`` would return, and leaves every other line to
``TextWrapper`` (tests/test_source_positions.py compares the two).
"""

from __future__ import annotations

import functools
import textwrap

_installed = False
_sources_installed = False


_BREAKS = frozenset("\t\n\x0b\x0c\r")
"""The whitespace ``TextWrapper`` expands or replaces before it wraps: a line with any of these
takes the wrapper's own path."""


class _FittingLineWrapper(textwrap.TextWrapper):
    """``TextWrapper(width=80)`` as Taichi's ``get_pos_info`` uses it (default options), with a
    shortcut for the common case: an ASCII line without tabs or line breaks that fits the width
    comes back as it is, less its trailing spaces, or as no line at all when it is blank, which is
    what the wrapper's chunking returns for it (a line's leading spaces stay; its trailing ones
    are dropped)."""

    def wrap(self, text: str) -> list:
        if len(text) <= self.width and text.isascii() and not _BREAKS.intersection(text):
            kept = text.rstrip(" ")
            return [kept] if kept else []
        return super().wrap(text)


def _position_key(ctx, node) -> tuple:
    body = getattr(node, "body", None)
    first = body[0].lineno if isinstance(body, list) and body and hasattr(body[0], "lineno") else None
    return (ctx.file, ctx.lineno_offset, ctx.func.func.__name__, ctx.indent, node.__class__.__name__, node.lineno,
            getattr(node, "end_lineno", None), getattr(node, "col_offset", None), getattr(node, "end_col_offset", None),
            first)


def memoise_source_positions() -> None:
    """Wrap ``ASTTransformerContext.get_pos_info`` with a cache (once per process)."""
    global _installed
    if _installed:
        return
    from taichi.lang.ast import ast_transformer_utils as utils

    original = utils.ASTTransformerContext.get_pos_info
    cache: dict = {}

    def get_pos_info(self, node):
        key = _position_key(self, node)
        info = cache.get(key)
        if info is None:
            info = original(self, node)
            cache[key] = info
        return info

    utils.ASTTransformerContext.get_pos_info = get_pos_info
    utils.TextWrapper = _FittingLineWrapper
    _installed = True


class _MemoisedTextwrap:
    """``textwrap`` as ``kernel_impl`` uses it (``fill`` and ``dedent``), each result kept."""

    fill = staticmethod(functools.lru_cache(maxsize=None)(textwrap.fill))
    dedent = staticmethod(functools.lru_cache(maxsize=None)(textwrap.dedent))

    def __getattr__(self, name):
        return getattr(textwrap, name)


def memoise_function_sources() -> None:
    """Keep each function's source lines and file, and the fills and dedents of its lines, for
    ``kernel_impl._get_tree_and_ctx`` (once per process)."""
    global _sources_installed
    if _sources_installed:
        return
    from taichi.lang import kernel_impl

    read_lines, read_file = kernel_impl.getsourcelines, kernel_impl.getsourcefile
    lines: dict = {}
    files: dict = {}

    def getsourcelines(obj):
        if obj not in lines:
            lines[obj] = read_lines(obj)
        src, first = lines[obj]
        return list(src), first

    def getsourcefile(obj):
        if obj not in files:
            files[obj] = read_file(obj)
        return files[obj]

    kernel_impl.getsourcelines = getsourcelines
    kernel_impl.getsourcefile = getsourcefile
    kernel_impl.textwrap = _MemoisedTextwrap()
    _sources_installed = True
