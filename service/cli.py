"""``flycrane serve``: run the HTTP service with uvicorn."""

from __future__ import annotations

import argparse


def _cmd_serve(args: argparse.Namespace) -> int:
    import uvicorn

    from service.app import create_app
    from service.settings import Settings

    overrides = {
        k: v for k, v in (("data_dir", args.data_dir), ("workers", args.workers)) if v is not None
    }
    settings = Settings(**overrides)
    uvicorn.run(create_app(settings), host=args.host, port=args.port, log_level="info")
    return 0


def register(commands: argparse._SubParsersAction) -> None:
    """Add ``serve`` to the ``flycrane`` command line (entry point ``flycrane.commands``)."""
    command = commands.add_parser("serve", help="run the HTTP mission service")
    command.add_argument("--host", default="127.0.0.1", help="address to listen on")
    command.add_argument("--port", type=int, default=8000)
    command.add_argument("--data-dir", help="database and artifacts (FLYCRANE_DATA_DIR)")
    command.add_argument("--workers", type=int, help="planning processes (FLYCRANE_WORKERS)")
    command.set_defaults(handler=_cmd_serve)
