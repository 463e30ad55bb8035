"""The web sandbox: a live viser world where users drop debris, select and remove bodies,
switch solvers and watch the jitter appear and vanish (``sandbox serve``).

The engine (``sandbox``) never imports this package: ``serve`` reaches the ``sandbox``
command through the ``sandbox.commands`` entry point (``web.cli.register``).
"""
