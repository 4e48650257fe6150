"""The controller's results do not depend on the backend switch (FRANKA_SIM_GYM_NATIVE).

The C replacement of the model terms it reads (sim/_dynamics.c) is held to its numpy
rule (docs/architecture.md,
"One implementation per rule"): the same command streams give the same published
states, bit for bit, with the optional kernels on and off. (A Cartesian stream goes
through the IK, sim's, whose kernel agrees with the numpy solve to rounding; it is not
part of this claim.)
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys

import pytest

from franka_sim_gym import native
from franka_sim_gym.fci import tables

STREAM = r"""
import hashlib
import numpy as np
from franka_sim_gym import native
from tests.fci_helpers import EXT, IMP, JP, JV, NONE, LoopClient, make_controller

digest = hashlib.sha256()
for generator, controller, field in ((JP, IMP, "q_c"), (JV, IMP, "dq_c"), (NONE, EXT, "tau_J_d")):
    ctrl = make_controller(2, enforce_motion_limits=True)
    clients = [LoopClient(ctrl, i) for i in range(2)]
    for client in clients:
        client.start(generator, controller)
    rng = np.random.default_rng(3)
    base = ctrl.states["q_d"].copy() if field == "q_c" else np.zeros((2, 7))
    for k in range(400):
        t = k * 1e-3
        value = base + 0.2 * np.sin(2 * np.pi * t) * np.array([0, 0, 0, 1, 0, 0, 0.5])
        if field == "dq_c":
            value = 0.2 * np.cos(2 * np.pi * t) * np.array([0, 0, 0, 1, 0, 0, 0.5])
        if field == "tau_J_d":
            value = 0.5 * np.sin(2 * np.pi * t) * np.ones((2, 7))
        if k == 300:
            value = value + 0.05  # a jump: a reflex under enforcement
        command = clients[0].command
        command["message_id"] = ctrl.states["message_id"]
        command[field] = value
        mask = rng.random(2) > 0.1  # some cycles lost
        ctrl.cycle(command, mask)
        digest.update(ctrl.states.tobytes())
print(native.ENABLED, digest.hexdigest())
"""


def _digest(switch: str) -> str:
    env = dict(os.environ, FRANKA_SIM_GYM_NATIVE=switch)
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    out = subprocess.run(
        [sys.executable, "-c", STREAM], env=env, cwd=root, capture_output=True, text=True
    )
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


def test_joint_and_torque_streams_publish_the_same_states_with_and_without_kernels():
    on, off = _digest("1"), _digest("0")
    assert on.split()[0] == "True" and off.split()[0] == "False"
    assert on.split()[1] == off.split()[1]
    assert hashlib.sha256().hexdigest() != on.split()[1]  # states were hashed


def test_kernels_are_built_where_a_compiler_is():
    """The install compiles the whole-rule replacements (setup.py); a silent fallback to
    numpy would leave the speed the benchmarks record unmeasured."""
    if shutil.which("cc") is None and shutil.which("gcc") is None:
        pytest.skip("no C compiler on this machine")
    if not native.ENABLED:
        pytest.skip("FRANKA_SIM_GYM_NATIVE=0")
    assert all(native.loaded().values()), f"not built: {native.describe()}; pip install -e ."


def test_the_kernels_difference_over_the_controllers_cycle():
    """Each module carries the cycle it was built for; load() refuses another."""
    assert native.CYCLE == tables.DELTA_T
    for name in native.MODULES:
        module = native.load(name)
        if module is not None:
            assert module.DELTA_T == tables.DELTA_T
