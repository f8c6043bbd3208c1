"""Run a command in a private network namespace, where only its own loopback exists.

SITL listens on every interface (``../shared/sitl/README.md``). A flight therefore runs
inside a new user and network namespace (``unshare --net --map-root-user``, no privileges
needed where unprivileged user namespaces are enabled): the simulators, our ground station
and their TCP connections live on a loopback nobody outside can reach, and vanish with it.
``--kill-child`` ties the command's life to ``unshare``'s: a caller that kills the
``unshare`` process by its PID (e.g. a test's timeout) kills the flight, and the flight's
simulators follow by their parent-death signal (:mod:`missions.sitl.process`).
"""

from __future__ import annotations

import shutil
import subprocess
from collections.abc import Sequence
from pathlib import Path

from missions.sitl.errors import SitlError

#: Interfaces of this process's network namespace (``/sys/class/net`` would show the
#: namespace sysfs was mounted in, not ours).
NET_DEVICES = Path("/proc/self/net/dev")


def isolated() -> bool:
    """Whether this process's network namespace has no interface but loopback."""
    lines = NET_DEVICES.read_text().splitlines()[2:]  # two header lines
    return [line.split(":", 1)[0].strip() for line in lines] == ["lo"]


def bring_up_loopback() -> None:
    """Set ``lo`` up (a new namespace starts with it down).

    Raises
    ------
    SitlError
        If iproute2's ``ip`` is missing or fails.
    """
    ip = shutil.which("ip") or "/usr/sbin/ip"
    try:
        subprocess.run([ip, "link", "set", "lo", "up"], check=True, capture_output=True)
    except (OSError, subprocess.CalledProcessError) as error:
        raise SitlError(f"cannot bring up loopback in the private namespace: {error}") from error


def isolated_command(command: Sequence[str]) -> list[str]:
    """``command`` wrapped to run in a new private network namespace.

    Raises
    ------
    SitlError
        If util-linux's ``unshare`` is not installed.
    """
    unshare = shutil.which("unshare")
    if unshare is None:
        raise SitlError("util-linux 'unshare' is needed to isolate SITL's network")
    return [unshare, "--net", "--map-root-user", "--kill-child=SIGKILL", "--", *command]


def namespaces_available() -> str | None:
    """None if a private network namespace can be made here, else the reason."""
    try:
        probe = subprocess.run(
            isolated_command(["true"]), capture_output=True, text=True, timeout=10
        )
    except (SitlError, OSError, subprocess.TimeoutExpired) as error:
        return str(error)
    if probe.returncode != 0:
        return f"unshare --net --map-root-user failed: {probe.stderr.strip()}"
    return None
