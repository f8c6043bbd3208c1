"""The team monitor names each fault once, with the drone, the time and what it saw."""

from __future__ import annotations

from missions.execution.team import EKF_NEEDED, FaultKind, MonitorLimits, TeamMonitor

GUIDED = 4


def healthy(monitor: TeamMonitor, t: float) -> None:
    for k in range(3):
        monitor.heard(k, t)
        monitor.observe(k, mode=GUIDED, system_status=4, ekf_flags=EKF_NEEDED | 0x100,
                        fix_type=6, error=0.02, attitude_error=1.0)  # fmt: skip


def test_a_healthy_team_has_no_fault():
    monitor = TeamMonitor(GUIDED)
    healthy(monitor, 10.0)
    assert monitor.faults(10.1) == []


def test_every_kind_of_fault_is_reported_once_for_its_drone():
    monitor = TeamMonitor(GUIDED, MonitorLimits(link_timeout=0.5, stray_distance=0.25,
                                                min_fix_type=3))  # fmt: skip
    healthy(monitor, 10.0)
    monitor.heard(0, 10.0)
    monitor.heard(1, 10.5)
    monitor.heard(2, 10.5)
    monitor.observe(1, mode=9)  # LAND
    monitor.observe(2, fix_type=1, ekf_flags=EKF_NEEDED & ~16, error=0.4, system_status=5,
                    attitude_error=7.5)  # fmt: skip
    faults = monitor.faults(10.6)
    seen = {(f.drone, f.kind) for f in faults}
    assert seen == {
        (1, FaultKind.LINK),
        (2, FaultKind.MODE),
        (3, FaultKind.GPS),
        (3, FaultKind.EKF),
        (3, FaultKind.STRAY),
        (3, FaultKind.FAILSAFE),
        (3, FaultKind.ATTITUDE),
    }
    assert all(f.time == 10.6 for f in faults)
    assert "mode 9, not 4" in next(str(f) for f in faults if f.kind is FaultKind.MODE)
    assert "7.5 deg" in next(str(f) for f in faults if f.kind is FaultKind.ATTITUDE)
    assert monitor.faults(10.7) == []  # each once
