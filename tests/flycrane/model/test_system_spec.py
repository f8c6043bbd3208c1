"""System descriptions: defaults, files, and errors that name the field."""

from __future__ import annotations

import json

import numpy as np
import pytest

from flycrane.errors import SystemSpecError
from flycrane.model.cable_system import CableSystem
from flycrane.model.system_spec import SystemSpec, load_system, save_system, system_from_dict


def test_defaults_are_the_benchmark_system():
    spec = SystemSpec()
    assert spec.geometry.kind == "octahedral"
    assert (spec.geometry.side, spec.geometry.cable_length) == (1.4, 2.0)
    assert spec.platform_mass == 1.5
    assert spec.drone_mass == (1.0,) * 3 and spec.max_thrust == (25.0,) * 3
    assert (spec.tension_min, spec.tension_max) == ((0.5,) * 6, (30.0,) * 6)
    assert SystemSpec(drone_mass=1.2).drone_mass == (1.2,) * 3
    np.testing.assert_allclose(
        spec.perturbation.ellipsoid_matrix(), np.diag([0.25] * 3 + [1 / 0.09] * 3)
    )


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_round_trip_through_a_file(tmp_path, suffix):
    spec = SystemSpec.model_validate(
        {
            "platform_mass": 2.5,
            "com_offset": [0.0, 0.1, -0.2],
            "drone_mass": [1.0, 1.1, 1.2],
            "tension_max": [30, 30, 28, 28, 30, 30],
            "perturbation": {"matrix": np.diag([0.3] * 3 + [10.0] * 3).tolist()},
        }
    )
    path = tmp_path / f"system{suffix}"
    save_system(spec, path)
    assert load_system(path) == spec


def test_generic_geometry_round_trip(tmp_path):
    data = {
        "geometry": {
            "kind": "generic",
            "platform_points": [
                [0.8, -0.1, 0],
                [0.8, 0.1, 0],
                [-0.3, 0.7, 0],
                [-0.5, 0.6, 0],
                [-0.5, -0.6, 0],
                [-0.3, -0.7, 0],
            ],
            "cable_lengths": [2.0] * 6,
        }
    }
    spec = system_from_dict(data)
    save_system(spec, tmp_path / "g.toml")
    assert load_system(tmp_path / "g.toml") == spec
    CableSystem.from_spec(spec)


@pytest.mark.parametrize(
    ("change", "field", "reason"),
    [
        ({"platform_mass": -1.0}, "platform_mass", "greater than 0"),
        ({"drone_mass": [1.0, -2.0, 1.0]}, "drone_mass[1]", "greater than 0"),
        (
            {"geometry": {"kind": "octahedral", "cable_length": 0.6}},
            "geometry",
            "half the platform",
        ),
        (
            {"perturbation": {"matrix": (-np.eye(6)).tolist()}},
            "perturbation.matrix",
            "positive definite",
        ),
        (
            {"perturbation": {"matrix": np.triu(np.ones((6, 6))).tolist()}},
            "perturbation.matrix",
            "symmetric",
        ),
        ({"perturbation": {"force": 0}}, "perturbation.force", "greater than or equal to 0.000001"),
        ({"tension_max": [30, 30, 0.2, 30, 30, 30]}, "system", "cable 3 upper bound"),
        ({"tension_min": [0.5] * 5}, "tension_min", "one number or 6 (one per cable), got 5"),
        ({"max_thrust": 9.0}, "system", "drone 1 thrust 9.0 N does not exceed"),
        ({"com_offset": [0, 0]}, "com_offset", ""),
        ({"colour": "red"}, "colour", "not permitted"),
        (
            {
                "geometry": {
                    "kind": "generic",
                    "platform_points": [[0, 0, 0]] * 6,
                    "cable_lengths": [2] * 6,
                }
            },
            "geometry",
            "distinct base points",
        ),
        (
            {
                "geometry": {
                    "kind": "generic",
                    "platform_points": [
                        [1, 0, 0],
                        [1, 0, 0.1],
                        [-0.5, 0.8, 0],
                        [-0.5, 0.8, 0.1],
                        [-0.5, -0.8, 0],
                        [0, 0, 4.9],
                    ],
                    "cable_lengths": [2] * 6,
                }
            },
            "geometry",
            "cannot form a triangle",
        ),
    ],
)
def test_bad_system_names_the_field(change, field, reason):
    with pytest.raises(SystemSpecError) as info:
        system_from_dict(change)
    fields = [p.field for p in info.value.problems]
    assert any(f.startswith(field) for f in fields), fields
    assert reason in str(info.value)


def test_bad_files_say_which_file_and_why(tmp_path):
    broken = tmp_path / "broken.toml"
    broken.write_text("platform_mass = [", encoding="utf-8")
    with pytest.raises(SystemSpecError, match=r"broken\.toml: file: not valid"):
        load_system(broken)
    negative = tmp_path / "negative.json"
    negative.write_text(json.dumps({"platform_mass": -3}), encoding="utf-8")
    with pytest.raises(SystemSpecError, match=r"negative\.json: platform_mass"):
        load_system(negative)
    (tmp_path / "x.yaml").write_text("platform_mass: 2", encoding="utf-8")
    with pytest.raises(SystemSpecError, match="unknown extension"):
        load_system(tmp_path / "x.yaml")
    with pytest.raises(SystemSpecError, match="file"):
        load_system(tmp_path / "missing.toml")
