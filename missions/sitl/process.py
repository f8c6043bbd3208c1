"""ArduCopter SITL processes: start N instances, know their PIDs, stop them for sure.

Each instance runs in its own working directory (SITL writes ``eeprom.bin``, logs and
terrain there) and serves MAVLink on TCP port ``5760 + 10 * index`` (SERIAL0), waiting for
that connection before it boots. SITL listens on every interface, so the instances must run
in a private network namespace (:mod:`missions.sitl.netns`); clients use 127.0.0.1.

Stopping: :meth:`SitlGroup.stop` sends SIGTERM to every PID, waits, then SIGKILL. Every
instance is also started under ``setpriv --pdeathsig KILL``, so the kernel kills it when the
process that started it dies, whatever the way (a test runner killed with SIGKILL, a crash):
no orphaned simulator is left. The PIDs are written to ``pids.json`` in the group's
directory for whoever must check that afterwards.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import signal
import subprocess
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from missions.sitl.errors import SitlError
from missions.sitl.settings import SitlSettings

logger = logging.getLogger(__name__)

#: SERIAL0 of instance 0; instance N adds 10 N (SITL's ``-I``).
BASE_PORT = 5760
#: How long a SIGTERM is given before SIGKILL [s].
TERMINATE_GRACE_S = 3.0
#: How long an instance may take to listen on its port [s of wall time].
LISTEN_TIMEOUT_S = 30.0
#: TCP sockets of this network namespace; state 0A is LISTEN.
TCP_TABLE = Path("/proc/self/net/tcp")


@dataclass(frozen=True)
class SitlHome:
    """Where an instance starts (and its home): WGS84 degrees, metres AMSL, heading [deg]."""

    latitude: float
    longitude: float
    altitude: float
    heading: float = 0.0

    def argument(self) -> str:
        return f"{self.latitude:.9f},{self.longitude:.9f},{self.altitude:.3f},{self.heading:g}"


@dataclass(frozen=True)
class SitlInstance:
    """One running simulator."""

    index: int
    system_id: int
    pid: int
    workdir: Path

    @property
    def address(self) -> str:
        """Our connection string for its SERIAL0."""
        return f"tcp:127.0.0.1:{BASE_PORT + 10 * self.index}"


#: BARO_GND_TEMP that makes SITL's barometric heights right [deg C]: SITL makes pressure
#: from the standard atmosphere, whose temperature is 15 C at sea level, while its default
#: ground temperature is guessed per instance from the simulated sensor and reads heights
#: a few per cent high, differently on each drone (BENCHMARKS.md, "Moved from code
#: comments").
SITL_BARO_GROUND_TEMPERATURE = 15.0


def defaults_file(settings: SitlSettings, directory: Path, scripting: bool = False) -> Path:
    """The defaults SITL boots with: the configured file, plus calibrated barometers
    (:attr:`SitlSettings.calibrated_barometers`), no artificial gyro drift
    (:attr:`SitlSettings.gyro_drift`) and, with ``scripting``, Lua scripts (SCR_ENABLE,
    read at boot). A defaults file is read before the barometers are calibrated: the only
    time BARO_GND_TEMP may change (:mod:`missions.autopilots.ardupilot`, "Parameters").
    The path returned is absolute: SITL reads it from its own working directory.

    Raises
    ------
    SitlError
        The configured file cannot be read (it names the setting and the file).
    """
    if not settings.defaults_file.is_file():
        raise SitlError(
            f"FLYCRANE_SITL_DEFAULTS: no defaults file {settings.defaults_file} (the SITL "
            "binary's copter.parm by default)"
        )
    extra = []
    if settings.calibrated_barometers:
        extra.append(f"BARO_GND_TEMP {SITL_BARO_GROUND_TEMPERATURE}")
    if not settings.gyro_drift:
        extra.append("SIM_DRIFT_SPEED 0")
    if scripting:
        extra.append("SCR_ENABLE 1")
    if not extra:
        return settings.defaults_file.resolve()
    path = directory.resolve() / "defaults.parm"
    base = settings.defaults_file.read_text(encoding="utf-8")
    path.write_text("\n".join([base.rstrip(), *extra]) + "\n", encoding="utf-8")
    return path


def sitl_command(
    settings: SitlSettings,
    index: int,
    system_id: int,
    home: SitlHome,
    defaults: Path,
    start_time: int | None = None,
) -> list[str]:
    """The command line of instance ``index`` (see ``../shared/sitl/README.md``);
    ``start_time`` [s since the Unix epoch]: the simulated clock's epoch, the same for every
    instance of a flight, so that their UNIX times (SYSTEM_TIME) are one common clock."""
    command = [
        str(settings.binary.resolve()),
        "-w",  # wipe stored parameters: every flight starts from the defaults file
        "--model",
        "quad",
        "--speedup",
        f"{settings.speedup:g}",
        "--defaults",
        str(defaults),
        "-I",
        str(index),
        "--sysid",
        str(system_id),
        "--home",
        home.argument(),
    ]
    if start_time is not None:
        command += ["--start-time", str(int(start_time))]
    if shutil.which("setpriv"):
        return ["setpriv", "--pdeathsig", "KILL", "--", *command]
    return command


class SitlGroup:
    """N SITL instances under ``directory`` (one subdirectory each). Use ``with``.

    Raises
    ------
    SitlError
        If the binary is missing or an instance exits during start-up.
    """

    def __init__(
        self,
        settings: SitlSettings,
        homes: list[SitlHome],
        directory: Path,
        first_sysid: int = 1,
        scripts: tuple[Path, ...] = (),
    ) -> None:
        self.settings = settings
        self.homes = homes
        # absolute: each instance runs in its own working directory
        self.directory = directory.resolve()
        self.first_sysid = first_sysid
        self.scripts = scripts  #: Lua scripts every instance runs (copied into scripts/)
        #: the simulated clocks' common epoch (``--start-time``)
        self.start_time = int(time.time())
        self.instances: list[SitlInstance] = []
        self._processes: list[subprocess.Popen[bytes]] = []
        self._owner = threading.get_ident()

    def start(self) -> list[SitlInstance]:
        if not self.settings.binary.is_file() or not os.access(self.settings.binary, os.X_OK):
            raise SitlError(f"no executable SITL binary at {self.settings.binary}")
        if threading.get_ident() != self._owner:
            # the parent-death signal follows the *thread* that forked: a pool thread that
            # ends would take the simulators with it
            raise SitlError("start SITL from the thread that created the group")
        self.directory.mkdir(parents=True, exist_ok=True)
        try:
            for index, home in enumerate(self.homes):
                workdir = self.directory / f"sitl{index}"
                workdir.mkdir(exist_ok=True)
                system_id = self.first_sysid + index
                defaults = defaults_file(self.settings, workdir, scripting=bool(self.scripts))
                if self.scripts:
                    (workdir / "scripts").mkdir(exist_ok=True)
                    for script in self.scripts:
                        shutil.copyfile(script, workdir / "scripts" / script.name)
                command = sitl_command(
                    self.settings, index, system_id, home, defaults, self.start_time
                )
                with open(workdir / "console.log", "wb") as console:
                    process = subprocess.Popen(
                        command,
                        cwd=workdir,
                        stdin=subprocess.DEVNULL,
                        stdout=console,
                        stderr=subprocess.STDOUT,
                    )
                self._processes.append(process)
                self.instances.append(SitlInstance(index, system_id, process.pid, workdir))
            (self.directory / "pids.json").write_text(
                json.dumps([i.pid for i in self.instances]), encoding="utf-8"
            )
            self._wait_listening()
        except BaseException:
            self.stop()
            raise
        logger.info("SITL started: %s", [(i.system_id, i.pid) for i in self.instances])
        return self.instances

    def _wait_listening(self) -> None:
        """Until every instance listens on its SERIAL0 port (read from the kernel's socket
        table: a probing connection would be taken for the ground station's)."""
        deadline = time.monotonic() + LISTEN_TIMEOUT_S
        ports = {BASE_PORT + 10 * i.index for i in self.instances}
        while not ports <= listening_tcp_ports():
            self.check_running()
            if time.monotonic() > deadline:
                raise SitlError(f"SITL ports {sorted(ports)} not listening in {LISTEN_TIMEOUT_S} s")
            time.sleep(0.02)

    def check_running(self) -> None:
        """Raise :class:`SitlError` with the end of its console if an instance exited."""
        for instance, process in zip(self.instances, self._processes, strict=True):
            if process.poll() is not None:
                log = (instance.workdir / "console.log").read_text(errors="replace")[-2000:]
                raise SitlError(
                    f"SITL instance {instance.index} exited with {process.returncode}: {log}"
                )

    def stop(self) -> None:
        """SIGTERM, wait, SIGKILL: every instance is gone when this returns. Idempotent."""
        for process in self._processes:
            if process.poll() is None:
                process.send_signal(signal.SIGTERM)
        deadline = time.monotonic() + TERMINATE_GRACE_S
        for process in self._processes:
            try:
                process.wait(timeout=max(deadline - time.monotonic(), 0.01))
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        self._processes.clear()

    def __enter__(self) -> list[SitlInstance]:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


def listening_tcp_ports() -> set[int]:
    """Local ports of the TCP sockets listening in this network namespace."""
    ports = set()
    for line in TCP_TABLE.read_text().splitlines()[1:]:
        fields = line.split()
        if fields[3] == "0A":
            ports.add(int(fields[1].rsplit(":", 1)[1], 16))
    return ports


def alive(pid: int) -> bool:
    """Whether a process ``pid`` exists (and is not a zombie)."""
    try:
        status = Path(f"/proc/{pid}/stat").read_text()
    except FileNotFoundError:
        return False
    return status.rsplit(")", 1)[1].split()[0] != "Z"
