"""The mock's parameters against the ground side (:mod:`missions.mavlink.params`), answered
as ArduCopter 4.5.7 answers them (measured on the SITL binary: ``docs/missions.md``)."""

from __future__ import annotations

import dataclasses

import pytest

from flycrane.errors import InputError
from missions.autopilots.ardupilot import ArduCopterSettings, team_parameters
from missions.mavlink.errors import ParameterError
from missions.mavlink.messages import dialect, param_request_read
from missions.mavlink.params import check_parameters, read_parameter, set_parameters
from missions.mavlink.policy import RetryPolicy
from missions.mavlink.transport import VehicleLink
from missions.mock.autopilot import MockConfig
from missions.mock.parameters import settings_from_parameters, stored_value
from tests.missions.loopback import HOME

#: ArduCopter 4.5.7's defaults, read from the binary (docs/missions.md, "Parameters").
DEFAULTS = {"WPNAV_SPEED": 1000.0, "WPNAV_SPEED_UP": 250.0, "WPNAV_SPEED_DN": 150.0,
            "WPNAV_ACCEL": 250.0, "WPNAV_ACCEL_Z": 100.0, "WPNAV_JERK": 1.0, "PSC_POSXY_P": 1.0,
            "PSC_VELXY_P": 2.0, "PSC_POSZ_P": 1.0, "PSC_VELZ_P": 5.0,
            "WP_YAW_BEHAVIOR": 2.0, "GUID_TIMEOUT": 3.0, "FS_GCS_ENABLE": 0.0,
            "EK3_SRC1_POSZ": 1.0}  # fmt: skip


def test_every_parameter_a_plan_sets_is_there_with_arducopters_default(spawn_mock, fast_policy):
    _, address = spawn_mock()
    plan = {**ArduCopterSettings().parameters(), **team_parameters("gnss")[0]}
    assert set(plan) == set(DEFAULTS)
    with VehicleLink(address, fast_policy) as link:
        link.wait_heartbeat()
        checks = check_parameters(link, DEFAULTS, fast_policy)
    assert all(c.ok for c in checks), [c for c in checks if not c.ok]


def test_set_parameters_are_confirmed_and_read_back(spawn_mock, fast_policy):
    mock, address = spawn_mock()
    plan = ArduCopterSettings().parameters()
    with VehicleLink(address, fast_policy) as link:
        link.wait_heartbeat()
        set_parameters(link, plan, fast_policy)
        assert all(c.ok for c in check_parameters(link, plan, fast_policy))
    assert mock.parameters.values["WPNAV_ACCEL"] == plan["WPNAV_ACCEL"] == 50.0


def test_an_unknown_name_gets_no_answer(spawn_mock):
    _, address = spawn_mock()
    quick = RetryPolicy(request_timeout_s=0.2, retries=1, heartbeat_timeout_s=3.0)
    with VehicleLink(address, quick, name="v") as link:
        link.wait_heartbeat()
        assert read_parameter(link, "FOO_BARX", quick) is None
        with pytest.raises(ParameterError) as error:
            set_parameters(link, {"FOO_BARX": 1.0}, quick)
    assert (error.value.vehicle, error.value.name, error.value.found) == ("v", "FOO_BARX", None)


def test_answers_carry_arducopters_type_and_index(spawn_mock, fast_policy):
    _, address = spawn_mock()
    with VehicleLink(address, fast_policy) as link:
        link.wait_heartbeat()
        with link.subscribe(("PARAM_VALUE",)) as inbox:
            link.send(param_request_read("WP_YAW_BEHAVIOR", link.target))
            answer = inbox.get(2.0)
    assert answer is not None
    # a request by name is answered with the index it asked for, -1, which is 65535 as uint16
    assert (answer.param_type, answer.param_index) == (dialect.MAV_PARAM_TYPE_INT8, 65535)
    assert answer.param_value == 2.0 and answer.param_count == len(DEFAULTS)


@pytest.mark.parametrize(
    ("value", "held"),
    [(0.999, 1.0), (2.5, 2.0), (-1.995, -2.0), (300.0, 127.0), (-300.0, -128.0)],
)
def test_integer_parameters_round_as_ap_param_set_float(value, held):
    """AP_Param::set_float adds 0.01 (away from zero), truncates and clamps to the type."""
    assert stored_value(value, dialect.MAV_PARAM_TYPE_INT8) == held


def test_float_parameters_come_back_in_float32():
    assert stored_value(123.4, dialect.MAV_PARAM_TYPE_REAL32) == pytest.approx(123.4, rel=1e-7)
    assert stored_value(123.4, dialect.MAV_PARAM_TYPE_REAL32) != 123.4


def test_the_navigation_model_reads_back_from_the_parameters_it_writes():
    """The mock's reading is the inverse of the ``.parm`` writing (units and names)."""
    settings = dataclasses.replace(
        ArduCopterSettings.for_acceleration(0.4), speed=3.0, speed_up=0.7, speed_down=0.4,
        jerk=2.0, position_p=1.5, velocity_p=2.5, position_p_z=0.8, velocity_p_z=4.0,
    )  # fmt: skip
    assert settings_from_parameters(settings.parameters()) == settings


def test_boot_values_replace_defaults_and_unknown_names_are_refused(spawn_mock, fast_policy):
    mock, _ = spawn_mock(MockConfig(home=HOME, parameters={"WPNAV_SPEED": 500.0}))
    assert mock.parameters.values["WPNAV_SPEED"] == 500.0
    with pytest.raises(InputError) as error:
        MockConfig(parameters={"WPNAV_SPEDE": 1.0})
    assert "parameters.WPNAV_SPEDE" in str(error.value)
