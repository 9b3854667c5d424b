# SPDX-License-Identifier: BSD-3-Clause
"""Configuration files from Python: loading, and errors naming file, line and key."""
import numpy as np
import pytest

import fnmpc


def test_load_scenario(triangle):
    sc = fnmpc.load_scenario(triangle)
    assert sc.name == "triangle"
    assert [v.name for v in sc.vehicles] == ["leader", "follower1", "follower2"]
    assert sc.vehicles[sc.leader].leader
    np.testing.assert_allclose(sc.vehicles[1].start[:2], [-2.0, 1.5])
    names = [n for n, _ in sc.vehicles[1].neighbours]
    assert names == ["leader", "follower2"]
    np.testing.assert_allclose(sc.vehicles[1].neighbours[0][1], [2.0, -1.5, 0.0])
    short = sc.shortened(26.0)  # the triangle keeps its 9 s landing allowance: more than 21 s
    assert short.duration == pytest.approx(26.0)
    assert sc.duration == pytest.approx(82.0)  # the original is unchanged
    with pytest.raises(fnmpc.ConfigError, match="landing allowance"):
        sc.shortened(20.0)


def test_load_vehicle(vehicle_file):
    p = fnmpc.load_vehicle(vehicle_file)
    assert p.mass == pytest.approx(1.37)
    np.testing.assert_allclose(p.inertia, [0.0123, 0.0136, 0.0107])
    assert p.throttle_coefficients.shape == (4, 4)
    assert p.throttle_coefficients[0, 0] == pytest.approx(1.295532269)


def test_load_sensors():
    import os
    from conftest import SOURCE_DIR
    s = fnmpc.load_sensors(os.path.join(SOURCE_DIR, "config", "sensors", "default.yaml"))
    assert s.mocap.rate_hz > 0
    assert s.relative.max_range > 0


def test_unknown_key_names_file_line_and_key(tmp_path, vehicle_file):
    lines = open(vehicle_file).read().splitlines()
    row = next(i for i, line in enumerate(lines) if line.startswith("arm_length")) + 1
    lines.insert(row, "arm_lenght: 0.3")  # misspelt duplicate after the real key
    bad = tmp_path / "bad.yaml"
    bad.write_text("\n".join(lines) + "\n")
    with pytest.raises(fnmpc.ConfigError) as info:
        fnmpc.load_vehicle(str(bad))
    err = info.value
    assert isinstance(err, ValueError)
    assert err.file == str(bad)
    assert err.line == row + 1
    assert err.key == "arm_lenght"
    assert "arm_lenght" in str(err)


def test_bad_value_names_key(tmp_path, vehicle_file):
    text = open(vehicle_file).read().replace("mass: 1.37", "mass: heavy")
    bad = tmp_path / "bad.yaml"
    bad.write_text(text)
    with pytest.raises(fnmpc.ConfigError) as info:
        fnmpc.load_vehicle(str(bad))
    assert info.value.key == "mass"
    assert info.value.line == 3


def test_missing_file():
    with pytest.raises(fnmpc.ConfigError) as info:
        fnmpc.load_scenario("/nonexistent/scenario.yaml")
    assert info.value.file == "/nonexistent/scenario.yaml"
    assert info.value.line is None


def test_parse_scenario_error_from_text():
    with pytest.raises(fnmpc.ConfigError) as info:
        fnmpc.parse_scenario("name: x\nduration: [1, 2]\n", name="inline")
    assert info.value.file == "inline"
    assert info.value.line is not None
