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
"""

from __future__ import annotations

_installed = False


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
