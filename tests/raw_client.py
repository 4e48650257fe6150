"""A raw-socket FCI client for the tests that send what libfranka never would."""

from __future__ import annotations

import socket
import time

import numpy as np

from franka_sim_gym.fci import frames
from franka_sim_gym.fci.wire import (
    ROBOT_COMMAND_DTYPE,
    ROBOT_STATE_DTYPE,
    ROBOT_STATE_SIZE,
    MotionGeneratorMode,
)
from franka_sim_gym.fci.wire import protocol as p


class RawClient:
    """TCP + UDP to a server, with replies matched by command_id."""

    def __init__(self, host: str, port: int = 1337, receive_buffer: int | None = None) -> None:
        """``receive_buffer``: a small SO_RCVBUF [bytes] set before connecting, for a
        client whose unread replies must back up quickly."""
        self.host = host
        if receive_buffer is None:
            self.tcp = socket.create_connection((host, port), timeout=5.0)
        else:
            self.tcp = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            self.tcp.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, receive_buffer)
            self.tcp.settimeout(5.0)
            self.tcp.connect((host, port))
        self.udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        # Like libfranka: states go to (TCP peer address, udp_port), so listen where
        # our TCP connection comes from.
        self.udp.bind((self.tcp.getsockname()[0], 0))
        self.udp.settimeout(1.0)
        self.udp_port = self.udp.getsockname()[1]
        self.decoder = p.FrameDecoder()
        self.replies: dict[int, p.Frame] = {}
        self.next_id = 0
        self.server_udp = None

    def close(self) -> None:
        self.tcp.close()
        self.udp.close()

    def send_raw(self, data: bytes) -> None:
        self.tcp.sendall(data)

    def request(self, command: int, payload: bytes = b"") -> int:
        command_id = self.next_id
        self.next_id += 1
        self.send_raw(p.encode_request(command, command_id, payload))
        return command_id

    def reply(self, command_id: int, timeout: float = 5.0) -> p.Frame:
        deadline = time.monotonic() + timeout
        while command_id not in self.replies:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise TimeoutError(f"no reply to request {command_id}")
            self.tcp.settimeout(remaining)
            data = self.tcp.recv(65536)
            if not data:
                raise ConnectionError("server closed the connection")
            for frame in self.decoder.feed(data):
                self.replies[frame.command_id] = frame
        return self.replies.pop(command_id)

    def connect(self, version: int = p.VERSION) -> tuple[int, int]:
        command_id = self.next_id
        self.next_id += 1
        self.send_raw(p.encode_connect_request(command_id, self.udp_port, version))
        return p.decode_connect_reply(self.reply(command_id).payload)

    def set_ne_to_ee(self, NE_T_EE: np.ndarray) -> tuple[tuple[float, ...], int]:
        """SetNEToEE with a row-major 4x4: (the column-major values sent, the reply status)."""
        wire = tuple(frames.to_wire(np.asarray(NE_T_EE, dtype=np.float64)).tolist())
        command_id = self.request(p.Command.kSetNEToEE, p.SetNEToEERequest(wire).payload())
        return wire, self.reply(command_id).payload[0]

    def shift_ee_along_z(self, z: float) -> tuple[np.ndarray, tuple[float, ...], np.ndarray]:
        """SetNEToEE to a pure offset ``z`` [m] along the nominal EE's z axis; asserts the
        robot accepted it and reflects it in NE_T_EE. Returns (NE_T_EE row-major, the
        column-major values sent, the state after)."""
        NE_T_EE = np.eye(4)
        NE_T_EE[2, 3] = z
        wire, status = self.set_ne_to_ee(NE_T_EE)
        assert status == p.SetterStatus.kSuccess
        state = self.latest_state()
        np.testing.assert_allclose(state["NE_T_EE"], wire, atol=1e-7)
        return NE_T_EE, wire, state

    def state(self) -> np.ndarray:
        """The next state datagram (remembering where commands must go)."""
        data, addr = self.udp.recvfrom(4096)
        assert len(data) == ROBOT_STATE_SIZE
        self.server_udp = addr
        return np.frombuffer(data, dtype=ROBOT_STATE_DTYPE)[0]

    def latest_state(self) -> np.ndarray:
        """The first state published after this call: what was queued is dropped.

        So a state read after a reply reflects the request it answered (the server
        applies a request, replies, then publishes the cycle's state: the reply can
        overtake that state, never the one after it).
        """
        self.udp.setblocking(False)
        try:
            while True:
                self.udp.recvfrom(4096)
        except BlockingIOError:
            pass
        finally:
            self.udp.settimeout(1.0)
        return self.state()

    def send_command(self, **fields) -> None:
        command = np.zeros((), dtype=ROBOT_COMMAND_DTYPE)
        for name, value in fields.items():
            command[name] = value
        self.udp.sendto(command.tobytes(), self.server_udp)

    def start_joint_position_move(self) -> tuple[int, np.ndarray]:
        """Move in joint-position mode; returns (the Move's request id, the first state of
        the motion). Asserts kMotionStarted."""
        move = self.request(
            p.Command.kMove,
            p.MoveRequest(
                0, 0, p.DEFAULT_DEVIATION, p.DEFAULT_DEVIATION, False, (0.0,) * 7
            ).payload(),
        )
        assert self.reply(move).payload[0] == p.MoveStatus.kMotionStarted
        state = self.latest_state()
        while state["motion_generator_mode"] != MotionGeneratorMode.kJointPosition:
            state = self.state()
        return move, state

    def finish(self, q: np.ndarray, limit: int = 3000) -> np.ndarray:
        """End the motion as libfranka's finishMotion does: answer every state with q_c =
        ``q`` and motion_generation_finished until a state shows no motion generator
        running (at most ``limit`` states); returns that state. A client that lags reads
        queued states, and its finish then arrives late, which the robot takes for the
        servo but not as the motion's end: libfranka repeats it, so this does too."""
        for _ in range(limit):
            state = self.state()
            if state["motion_generator_mode"] == MotionGeneratorMode.kIdle:
                return state
            self.send_command(
                message_id=int(state["message_id"]), q_c=q, motion_generation_finished=True
            )
        raise AssertionError(f"the motion did not end within {limit} states")

    def hold(self, q: np.ndarray, cycles: int, finished: bool = False) -> np.ndarray:
        """Answer ``cycles`` states with q_c = ``q`` (the last with motion_generation_finished
        if ``finished``); returns the last state read."""
        for k in range(cycles):
            state = self.state()
            self.send_command(
                message_id=int(state["message_id"]),
                q_c=q,
                motion_generation_finished=finished and k == cycles - 1,
            )
        return state
