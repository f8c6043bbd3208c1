"""``flycrane serve``: run the HTTP service with uvicorn.

It listens on 127.0.0.1 unless told otherwise, and refuses another address without
``FLYCRANE_API_TOKEN`` unless ``--allow-unauthenticated`` says that this is meant (for
example behind a reverse proxy that authenticates; README "Security").
"""

from __future__ import annotations

import argparse
import ipaddress
import re
import sys

from pydantic import ValidationError
from pydantic_settings import SettingsError

from flycrane.errors import field_messages


def _loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _port(text: str) -> int:
    """An argparse type: a TCP port to listen on."""
    try:
        port = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if not 1 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"{port} is outside 1-65535")
    return port


def _cmd_serve(args: argparse.Namespace) -> int:
    import uvicorn

    from service.app import create_app
    from service.errors import DataDirLockedError, StartupError
    from service.settings import Settings
    from service.startup import open_storage

    options = {"data_dir": "--data-dir", "workers": "--workers"}
    overrides = {k: getattr(args, k) for k in options if getattr(args, k) is not None}
    try:
        settings = Settings(**overrides)
    except ValidationError as error:
        for field, message in field_messages(error.errors()):
            name = options[field] if field in overrides else f"FLYCRANE_{field.upper()}"
            print(f"flycrane serve: {name}: {message}", file=sys.stderr)
        return 2
    except SettingsError as error:  # a list setting that is not JSON
        found = re.search(r'field "(\w+)"', str(error))
        name = f"FLYCRANE_{found.group(1).upper()}" if found else "a FLYCRANE_ setting"
        print(f'flycrane serve: {name}: not JSON: a list is written as JSON, e.g. ["a", "b"]',
              file=sys.stderr)  # fmt: skip
        return 2
    if settings.api_token is None and not _loopback(args.host) and not args.allow_unauthenticated:
        print(
            f"flycrane serve: refusing to listen on {args.host} without FLYCRANE_API_TOKEN "
            "(anyone who reaches it could plan and upload missions); set a token, or pass "
            "--allow-unauthenticated if a proxy in front authenticates",
            file=sys.stderr,
        )
        return 2
    # The lifespan checks again; this turns a second server on the same directory, a full
    # disk or an unusable database into one line instead of uvicorn's traceback.
    try:
        lock, engine = open_storage(settings)
    except (DataDirLockedError, StartupError) as error:
        print(f"flycrane serve: {error}", file=sys.stderr)
        return 1
    engine.dispose()
    lock.release()
    if settings.dask_scheduler is not None:  # the same: a scheduler that does not answer
        from flycrane.execution import DaskExecutor

        try:
            DaskExecutor(settings.dask_scheduler).shutdown()
        except OSError as error:
            print(f"flycrane serve: FLYCRANE_EXECUTOR: no Dask scheduler answers at "
                  f"{settings.dask_scheduler} ({error})", file=sys.stderr)  # fmt: skip
            return 1
    uvicorn.run(
        create_app(settings),
        host=args.host,
        port=args.port,
        log_level="info",
        proxy_headers=args.proxy_headers,
        forwarded_allow_ips=args.forwarded_allow_ips,
    )
    return 0


def register(commands: argparse._SubParsersAction) -> None:
    """Add ``serve`` to the ``flycrane`` command line (entry point ``flycrane.commands``)."""
    command = commands.add_parser("serve", help="run the HTTP mission service")
    command.add_argument("--host", default="127.0.0.1", help="address to listen on")
    command.add_argument("--port", type=_port, default=8000, help="TCP port, 1-65535")
    command.add_argument("--data-dir", help="database and artifacts (FLYCRANE_DATA_DIR)")
    command.add_argument("--workers", type=int, help="planning processes (FLYCRANE_WORKERS)")
    command.add_argument(
        "--allow-unauthenticated",
        action="store_true",
        help="listen on a non-loopback address without FLYCRANE_API_TOKEN",
    )
    command.add_argument(
        "--proxy-headers",
        action="store_true",
        help="trust X-Forwarded-Proto/For from --forwarded-allow-ips (behind a reverse proxy)",
    )
    command.add_argument(
        "--forwarded-allow-ips",
        default="127.0.0.1",
        help="proxies whose X-Forwarded-* headers are trusted (default 127.0.0.1)",
    )
    command.set_defaults(handler=_cmd_serve)
