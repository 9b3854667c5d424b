# SPDX-License-Identifier: BSD-3-Clause
"""The shipped OCPs from Python: build, set references, step, read predictions and stats."""
import numpy as np
import pytest

import fnmpc

G = 9.81


def hover_thrust():
    return 1.37 * G  # the spec vehicle's mass is 1.37 kg (Table 1 of the reference work)


def test_leader_holds_hover():
    x0 = np.array([0, 0, 1, 0, 0, 0, 0, 0, 0], dtype=float)
    ocp = fnmpc.LeaderOcp(x0)
    assert (ocp.nx, ocp.nu, ocp.ny, ocp.nyn, ocp.np) == (9, 3, 11, 8, 1)
    y = np.zeros(ocp.ny)
    y[2] = 1.0  # position reference (0, 0, 1), everything else zero
    for k in range(ocp.horizon):
        ocp.set_reference(k, y)
    ocp.set_terminal_reference(y[:ocp.nyn])
    u = ocp.step(x0)
    st = ocp.stats
    assert st["status"] == "success" and not st["fallback"]
    assert st["sqp_iterations"] >= 1
    assert u[0] == pytest.approx(hover_thrust(), rel=0.02)
    assert abs(u[1]) < 1e-3 and abs(u[2]) < 1e-3
    assert ocp.states.shape == (ocp.horizon + 1, 9)
    assert ocp.inputs.shape == (ocp.horizon, 3)
    np.testing.assert_allclose(ocp.states[:, 2], 1.0, atol=1e-3)


def test_leader_moves_towards_reference():
    x0 = np.array([0, 0, 1, 0, 0, 0, 0, 0, 0], dtype=float)
    ocp = fnmpc.LeaderOcp(x0)
    y = np.zeros(ocp.ny)
    y[:3] = [1.0, 0.0, 1.0]
    for k in range(ocp.horizon):
        ocp.set_reference(k, y)
    ocp.set_terminal_reference(y[:ocp.nyn])
    u = ocp.step(x0)
    assert ocp.stats["status"] == "success"
    assert u[2] > 0.01  # positive pitch accelerates along +x (ZYX, thrust along body z)
    x = ocp.states[:, 0]
    assert x[-1] > x[0] + 0.05 and np.all(np.diff(x) >= -1e-9)
    assert ocp.kkt(x0) < 1e-4


def test_leader_benchmark_reference_closed_loop():
    ref = fnmpc.ReferenceTrajectory("nominal")
    p, v = ref.sample(0.0)
    x = np.concatenate([p, v, np.zeros(3)])
    ocp = fnmpc.LeaderOcp(x)
    for step in range(10):
        ocp.set_references(ref, step * ocp.sample_time)
        u = ocp.step(x)
        assert not ocp.stats["fallback"]
        x = ocp.states[1].copy()  # the model's own prediction as the plant
        ocp.shift()
    assert np.all(np.isfinite(u))


def test_bad_input_raises():
    ocp = fnmpc.LeaderOcp(np.zeros(9))
    with pytest.raises(ValueError):
        ocp.step(np.full(9, np.nan))
    with pytest.raises(IndexError):
        ocp.set_reference(ocp.horizon, np.zeros(ocp.ny))
    with pytest.raises(TypeError):
        ocp.step(np.zeros(4))


def neighbours_at(offsets, shift=(0.0, 0.0, 0.0)):
    return [fnmpc.NeighbourState(rel_pos=np.asarray(d) + (np.asarray(shift) if j == 0 else 0))
            for j, d in enumerate(offsets)]


@pytest.mark.parametrize("cls", [fnmpc.FollowerOcp, fnmpc.ReducedFollowerOcp])
def test_follower_in_formation_hovers(cls):
    d = fnmpc.desired_offsets()
    nb = neighbours_at(d)
    own = np.zeros(6)
    ocp = cls(own, nb)
    if cls is fnmpc.ReducedFollowerOcp:
        x0 = ocp.set_stage(own, nb)
        assert x0.shape == (9,)
    else:
        x0 = fnmpc.follower_state(own, nb)
        assert x0.shape == (22,)
    u = ocp.step(x0)
    assert ocp.stats["status"] == "success"
    assert u[0] == pytest.approx(hover_thrust(), rel=0.02)
    assert abs(u[1]) < 1e-3 and abs(u[2]) < 1e-3


@pytest.mark.parametrize("cls", [fnmpc.FollowerOcp, fnmpc.ReducedFollowerOcp])
def test_follower_closes_the_gap(cls):
    # Neighbour 1 is 1 m further along +x than desired: the follower must move along +x.
    d = fnmpc.desired_offsets()
    nb = neighbours_at(d, shift=(1.0, 0.0, 0.0))
    own = np.zeros(6)
    ocp = cls(own, nb)
    x0 = ocp.set_stage(own, nb) if cls is fnmpc.ReducedFollowerOcp else fnmpc.follower_state(own, nb)
    u = ocp.step(x0)
    assert ocp.stats["status"] == "success"
    assert u[2] > 0.01
    assert ocp.states[-1, 3 if cls is fnmpc.ReducedFollowerOcp else 0] > 0.05  # v_x at the end
