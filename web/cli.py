"""``sandbox serve``: registered with the ``sandbox`` command as a plugin (see pyproject)."""

from __future__ import annotations

from pathlib import Path


def register(sub) -> None:
    from sandbox import FORMULATIONS, SOLVERS

    serve = sub.add_parser("serve", help="the web sandbox: a live world in the browser",
                           description="Start the web sandbox and print its URL. Without SCENE: a scene sized "
                           "for the machine (playground on CPU, headline_pile with CUDA).")
    serve.add_argument("scene", nargs="?", help="a scene file or shipped scene name (see `sandbox scenes`)")
    serve.add_argument("--host", default="127.0.0.1", help="interface to listen on (0.0.0.0: every interface)")
    serve.add_argument("--port", type=int, default=8080, help="0 picks a free port (default 8080)")
    serve.add_argument("--arch", choices=["cpu", "cuda", "auto"], default="auto",
                       help="auto: CUDA when a device is present, else CPU")
    serve.add_argument("--solver", choices=list(SOLVERS), default="mass-splitting")
    serve.add_argument("--iterations", type=int, default=15)
    serve.add_argument("--formulation", choices=list(FORMULATIONS), default=None,
                       help="soft-step (Box2D v3) or paper (Tonge et al.: one step, Baumgarte); default: the scene's")
    serve.add_argument("--recordings", default="recordings", help="folder for saved recordings")
    serve.set_defaults(func=cmd_serve)


def cmd_serve(args) -> int:
    from sandbox import SandboxError

    from .app import SandboxApp

    if not 0 <= args.port <= 65535:
        raise SandboxError(f"--port must be in 0..65535, got {args.port}")
    if args.iterations < 1:
        raise SandboxError(f"--iterations must be at least 1, got {args.iterations}")
    app = SandboxApp(args.scene, host=args.host, port=args.port, arch=args.arch, solver=args.solver,
                     iterations=args.iterations, formulation=args.formulation, recordings_dir=Path(args.recordings))
    app.serve_forever()
    return 0
