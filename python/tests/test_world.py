# SPDX-License-Identifier: BSD-3-Clause
"""The simulator world from Python, with a controller written in Python in the loop."""
import numpy as np
import pytest

import fnmpc


def test_world_from_scenario(triangle):
    sc = fnmpc.load_scenario(triangle)
    world = fnmpc.World.from_scenario(sc, seed=4)
    assert world.num_vehicles == 3
    assert world.time == 0.0
    pos = world.positions()
    assert pos.shape == (3, 3)
    np.testing.assert_allclose(pos[:, :2], [v.start[:2] for v in sc.vehicles], atol=1e-6)
    world.step(0.5)
    assert world.time == pytest.approx(0.5)
    m = world.pop_measurements()
    assert m.dtype.names[:4] == ("kind", "vehicle", "stamp", "arrival")
    kinds = set(m["kind"].astype(str))
    assert {"mocap", "imu", "compass", "battery"} <= kinds
    assert np.all(m["arrival"] <= 0.5 + 1e-12)
    assert np.all(np.diff(m["arrival"]) >= 0)
    mocap = m[m["kind"] == b"mocap"]
    assert np.all(np.isfinite(mocap["position"]))
    assert np.all(np.isnan(mocap["voltage"]))
    assert len(world.pop_measurements()) == 0  # all popped


def test_python_controller_lifts_one_vehicle(triangle):
    """A PD altitude loop on the motion-capture height flies vehicle 0 to 1 m."""
    sc = fnmpc.load_scenario(triangle)
    world = fnmpc.World.from_scenario(sc)
    mass = sc.vehicles[0].params.mass
    z, vz, target = None, 0.0, 1.0
    for _ in range(int(6.0 / 0.02)):
        for r in world.pop_measurements():
            if r["kind"] == b"mocap" and r["vehicle"] == 0:
                z_new = r["position"][2]
                if z is not None:
                    vz = 0.7 * vz + 0.3 * (z_new - z) / (1.0 / 60.0)
                z = z_new
        thrust = mass * 9.81 + (0.0 if z is None else mass * (4.0 * (target - z) - 3.0 * vz))
        world.set_command(0, float(np.clip(thrust, 0.0, 25.0)), 0.0, 0.0, 0.0)
        world.step(0.02)
    state = world.true_state(0)
    assert state["position"][2] == pytest.approx(target, abs=0.1)
    assert abs(state["velocity"][2]) < 0.2
    assert world.true_state(1)["position"][2] < 0.15  # the others stayed on the ground


def test_bad_commands_raise(triangle):
    world = fnmpc.World.from_scenario(fnmpc.load_scenario(triangle))
    with pytest.raises(IndexError):
        world.set_command(3, 10.0, 0.0, 0.0, 0.0)
    with pytest.raises(ValueError):
        world.set_command(0, float("nan"), 0.0, 0.0, 0.0)
