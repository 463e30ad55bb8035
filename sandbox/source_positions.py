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
"""

from __future__ import annotations

import functools
import textwrap

_installed = False
_sources_installed = False


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
