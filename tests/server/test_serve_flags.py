"""The README's `serve` flags on the installed `franka-sim-gym` command, each judged by
what a client sees: --port (the port that answers), --robot fer (the FCI version it
speaks), --urdf (what GetRobotModel serves), --scene (an object the arm rests on: contact
and wrench in the state), --payload (the unannounced mass in the wrench estimate) and
--joint-discontinuity-scale (a Cartesian ramp the FR3's joint side refuses, passed)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from franka_sim_gym.fci.errors import Error
from franka_sim_gym.fci.wire import RobotMode
from franka_sim_gym.fci.wire import protocol as p
from franka_sim_gym.server.check import wait_until_ready
from franka_sim_gym.server.testing import SimServer, free_loopback_address
from franka_sim_gym.sim.world import URDF_PATH
from tests.profiles import positions, there_and_back
from tests.raw_client import RawClient
from tests.socket_helpers import motion_summaries

pytestmark = pytest.mark.socket

#: The console script `pip install` puts beside the interpreter.
COMMAND = Path(sys.executable).with_name("franka-sim-gym")
#: A box whose top is 1 cm above the flange at the home pose: the arm rests on it.
SHELF = """<mujoco model="shelf">
  <worldbody>
    <body name="shelf" pos="0.307 0 0.59">
      <geom name="shelf" type="box" size="0.05 0.05 0.01"/>
    </body>
  </worldbody>
</mujoco>
"""


def serve(*flags: str, port: int = p.COMMAND_PORT, log: Path) -> SimServer:
    """`franka-sim-gym serve --host <free loopback address> FLAGS`, ready."""
    host = free_loopback_address()
    with open(log, "w") as out:
        process = subprocess.Popen(
            [str(COMMAND), "serve", "--host", host, *flags],
            stdout=out,
            stderr=subprocess.STDOUT,
            env=os.environ.copy(),
        )
    server = SimServer(host, process, log, flags)
    why = wait_until_ready(host, port, timeout=60, alive=server.alive)
    if why is not None:
        server.stop()
        raise AssertionError(f"serve {' '.join(flags)} not ready: {why}\n{server.log()}")
    return server


def test_the_installed_command_serves_each_documented_flag(tmp_path, client):
    assert COMMAND.is_file(), f"{COMMAND}: the package's console script is not installed"
    urdf = tmp_path / "robot.urdf"
    marked = URDF_PATH.read_text().replace("<robot", "<!-- served from --urdf -->\n<robot", 1)
    urdf.write_text(marked)
    port = 1400
    flags = ("--port", str(port), "--robot", "fer", "--urdf", str(urdf), "--no-gripper")
    # In lockstep, so that a loaded machine loses no cycle of the motion below.
    server = serve(*flags, "--lockstep", "--enforce-motion-limits", port=port, log=tmp_path / "a")
    try:
        with pytest.raises(ConnectionRefusedError):  # --port: nothing on 1337
            RawClient(server.host)
        raw = RawClient(server.host, port=port)
        assert raw.connect() == (p.ConnectStatus.kSuccess, p.VERSION)
        # --urdf: GetRobotModel serves the file.
        reply = raw.reply(raw.request(p.Command.kGetRobotModel))
        assert reply.payload[0] == p.GetterStatus.kSuccess
        assert b"served from --urdf" in reply.payload
        # --robot fer: joint 1 at 2.4 rad/s, within the FR3's 2.62 and past the FER's
        # 2.175 (fci/tables.py), is the FER's velocity-limits violation.
        _, state = raw.start_joint_position_move()
        q = state["q_d"].astype(float)
        for offset in positions(there_and_back(2.4, 5.0, 500.0))[1:]:
            state = raw.state()
            if state["robot_mode"] != RobotMode.kMove:
                break
            raw.send_command(message_id=int(state["message_id"]), q_c=q + [offset, *[0] * 6])
        state = raw.latest_state()
        assert state["robot_mode"] == RobotMode.kReflex
        assert state["reflex_reason"][Error.joint_motion_generator_velocity_limits_violation]
        raw.close()
    finally:
        server.stop()

    # --scene: the arm rests on a shelf; 800 cycles on, contact along z, pressed up.
    shelf = tmp_path / "shelf.xml"
    shelf.write_text(SHELF)
    server = serve("--scene", str(shelf), "--no-gripper", log=tmp_path / "b")
    try:
        raw = RawClient(server.host)
        raw.connect()
        first = int(raw.state()["message_id"])
        state = raw.state()
        while int(state["message_id"]) - first < 800:
            state = raw.state()
        assert state["cartesian_contact"][2] == 1, state["cartesian_contact"]
        assert state["O_F_ext_hat_K"][2] < -20.0, state["O_F_ext_hat_K"]
        raw.close()
    finally:
        server.stop()

    # --payload: 1 kg on the flange the robot was not told of, in the wrench estimate;
    # --joint-discontinuity-scale 2: a 3.5 m/s^2 Cartesian ramp, refused by the FR3's
    # joint side (cartesian_motion_generator_joint_velocity_discontinuity at 11 rad/s^2
    # on the default scale), runs.
    flags = ("--payload", "1.0,0,0,0.05", "--joint-discontinuity-scale", "2")
    server = serve(*flags, "--lockstep", "--enforce-motion-limits", log=tmp_path / "c")
    try:
        r = client("pylibfranka_cartesian", "fast_ramp", server.host)
    finally:
        server.stop()
    np.testing.assert_allclose(r["O_F_ext_hat_K_at_rest"][:3], [0, 0, 9.81], atol=0.2)
    assert r["error"] is None, r
    assert r["moved"] == pytest.approx(r["distance"], abs=2e-3)
    assert motion_summaries(server.log()) == [("kSuccess", 0, 0)]
