"""The Franka Hand behind libfranka's gripper protocol v3 (TCP 1338 + UDP GripperState).

Wire format: docs/wire-protocol.md §10 (10-byte header with a u16 command;
Connect/Homing/Grasp/Move/Stop of 14/10/50/26/10 bytes; replies carry a u16
status; a 23-byte GripperState datagram). Statuses and what libfranka makes of
them: docs/errors.md §2.4. Behaviour: docs/fci-behaviour.md "Gripper
fidelity".

Threads:

* an accept thread accepts connections; the one that completes a valid Connect
  holds the hand (a second is refused and logged; one that sends no Connect
  within 2 s is closed: :mod:`~franka_sim_gym.server.client_slot`);
* each connection's reader thread decodes frames and posts requests; it never
  blocks on a running command, so a Stop sent mid-Grasp is read at once; its
  replies leave through the connection's outbox, so neither the reader nor the
  timer ever waits on a client that does not read;
* a timer thread applies the posted requests, steps the hand model at
  ``STEP_HZ`` (the kinematic :class:`FrankaHand` advances; the physics
  :class:`~franka_sim_gym.sim.physics_hand.PhysicsHand` polls its MuJoCo
  fingers), answers each command when its action finishes, and broadcasts
  GripperState at ``BROADCAST_HZ`` to (client IP, udp_port from Connect).

The protocol is the same for both backends: only the finger model differs.
"""

from __future__ import annotations

import logging
import queue
import socket
import struct
import threading
import time
from collections.abc import Callable
from enum import IntEnum

import numpy as np

from ..fci.wire import GRIPPER_STATE_DTYPE
from ..fci.wire.protocol import Frame, FrameDecoder, FramingError
from ..sim.gripper import TEMPERATURE_C, FrankaHand, HandModel, Outcome
from .client_slot import ClientSlot, stop_serving
from .logging_util import RateLimitedLog
from .request_queue import apply_pending
from .tcp_session import TcpSession

log = logging.getLogger("franka_sim_gym.gripper")

GRIPPER_PORT = 1338  # docs/wire-protocol.md §10
VERSION = 3  # docs/wire-protocol.md §10: gripper server version 3
HEADER = struct.Struct("<HII")  # §10.1: command u16, command_id u32, size u32 (total)
#: Our bound on one request: the largest real one (Grasp) is 50 bytes.
MAX_REQUEST_SIZE = 256
#: Model step (and physics poll) rate: our choice, 4 ms resolution on a motion.
STEP_HZ = 250
BROADCAST_HZ = 60.0  # docs/fci-behaviour.md "Gripper fidelity": GripperState over UDP at 60 Hz
_STATUS = struct.Struct("<H")
_CONNECT_REQ = struct.Struct("<HH")  # version, udp_port
_GRASP_REQ = struct.Struct("<ddddd")  # width, epsilon inner, epsilon outer, speed, force
_MOVE_REQ = struct.Struct("<dd")  # width, speed


class Command(IntEnum):
    """§10.2 command ids."""

    kConnect = 0
    kHoming = 1
    kGrasp = 2
    kMove = 3
    kStop = 4


class Status(IntEnum):
    """§10.2 status of Homing/Grasp/Move/Stop (Connect: 0 success, 1 incompatible)."""

    kSuccess = 0
    kFail = 1
    kUnsuccessful = 2
    kAborted = 3


#: §10.2 total request sizes, header included.
REQUEST_SIZE = {
    Command.kConnect: 14,
    Command.kHoming: 10,
    Command.kGrasp: 50,
    Command.kMove: 26,
    Command.kStop: 10,
}


def encode_reply(command: int, command_id: int, status: int, version: int | None = None) -> bytes:
    """A reply: header, u16 status, and for Connect the u16 server version (§10.2)."""
    body = _STATUS.pack(status) + (b"" if version is None else _STATUS.pack(version))
    return HEADER.pack(command, command_id, HEADER.size + len(body)) + body


class GripperSession(TcpSession):
    """The TCP side of one gripper client (connected once its Connect succeeded)."""

    host: GripperServer

    def __init__(self, server: GripperServer, sock: socket.socket, peer: tuple[str, int]) -> None:
        self._decoder = FrameDecoder(max_message_size=MAX_REQUEST_SIZE, header=HEADER)
        super().__init__(server, sock, peer, "gripper ", log, self._decoder.feed, self._handle)

    def reply(self, command: int, command_id: int, status: int, version: int | None = None):
        """Queue a reply; never blocks (a client that does not read is dropped)."""
        self.send(encode_reply(command, command_id, int(status), version))

    def _handle(self, item: Frame | FramingError) -> None:
        if isinstance(item, FramingError):
            # Every request is answered: libfranka has no reply timeout.
            log.warning(
                "gripper client %s: bad-frame (command %d, id %d): %s: answered kFail",
                self.peer,
                item.command,
                item.command_id,
                item.reason,
            )
            self.reply(item.command, item.command_id, Status.kFail)
        else:
            self._dispatch(item)

    def _fail(self, frame: Frame, reason: str, message: str) -> None:
        """Answer status 1: kFail, or for Connect kIncompatibleLibraryVersion (+ version)."""
        connect = frame.command == Command.kConnect
        log.warning(
            "gripper client %s: %s (command %d, id %d): %s: answered %s",
            self.peer,
            reason,
            frame.command,
            frame.command_id,
            message,
            "kIncompatibleLibraryVersion" if connect else "kFail",
        )
        self.reply(frame.command, frame.command_id, 1, VERSION if connect else None)

    def _dispatch(self, frame: Frame) -> None:
        try:
            command = Command(frame.command)
        except ValueError:
            self._fail(frame, "unknown-command", f"no gripper command {frame.command}")
            return
        size = HEADER.size + len(frame.payload)
        if size != REQUEST_SIZE[command]:
            self._fail(
                frame, "wrong-size", f"{command.name} is {REQUEST_SIZE[command]} bytes, got {size}"
            )
            return
        if command == Command.kConnect:
            version, udp_port = _CONNECT_REQ.unpack(frame.payload)
            if version != VERSION:
                log.warning(
                    "gripper client %s: library version %d is not %d: answered "
                    "kIncompatibleLibraryVersion",
                    self.peer,
                    version,
                    VERSION,
                )
                self.reply(frame.command, frame.command_id, 1, VERSION)
                return
            self.connect(encode_reply(frame.command, frame.command_id, 0, VERSION), udp_port)
            return
        if self.udp_port is None:
            self._fail(frame, "before-connect", f"{command.name} before Connect")
            return
        if command == Command.kGrasp:
            args = _GRASP_REQ.unpack(frame.payload)
        elif command == Command.kMove:
            args = _MOVE_REQ.unpack(frame.payload)
        else:
            args = ()
        self.host.submit(self, command, frame.command_id, args)


class GripperServer:
    """Serves one simulated Franka Hand to one libfranka gripper client at a time.

    Args:
        host: bind address (the robot server's).
        port: TCP port (1338; libfranka takes no port argument).
        object_width: a rigid virtual object between the fingers [m], or None
            (for the default kinematic hand).
        hand: the hand model to serve instead of a kinematic ``FrankaHand``
            (``--gripper-physics`` passes a ``PhysicsHand``).
    """

    def __init__(
        self,
        host: str = "127.0.0.1",
        port: int = GRIPPER_PORT,
        object_width: float | None = None,
        hand: HandModel | None = None,
    ) -> None:
        self.host, self.port = host, port
        self.hand = hand if hand is not None else FrankaHand(object_width=object_width)
        self._requests: queue.SimpleQueue[Callable[[], None]] = queue.SimpleQueue()
        self._pending: dict[int, tuple[GripperSession, Command, int]] = {}
        self._slot = ClientSlot("gripper ", lambda sock, peer: GripperSession(self, sock, peer))
        self._client_addr: tuple[str, int] | None = None
        self._running = threading.Event()
        self._wake = threading.Event()
        self._threads: list[threading.Thread] = []
        self._udp_log = RateLimitedLog(log)
        self._state = np.zeros(1, dtype=GRIPPER_STATE_DTYPE)
        self._message_id = 0

    # -- lifecycle ----------------------------------------------------------------------------

    def start(self) -> None:
        """Bind the sockets and start the threads."""
        self._tcp = socket.create_server((self.host, self.port))
        self._tcp.settimeout(0.2)
        self._udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._udp.bind((self.host, 0))
        self._running.set()
        accept = lambda: self._slot.accept_loop(self._tcp, self._running)  # noqa: E731
        for target, name in ((self._timer_loop, "gripper-timer"), (accept, "gripper-accept")):
            thread = threading.Thread(target=target, name=name, daemon=True)
            thread.start()
            self._threads.append(thread)
        log.info(
            "serving the Franka Hand (gripper protocol v%d, %s backend) on %s:%d "
            "(object width: %s)",
            VERSION,
            "kinematic" if isinstance(self.hand, FrankaHand) else "physics",
            self.host,
            self.port,
            self.hand.object_width,
        )

    def stop(self) -> None:
        """Stop the threads and close every socket."""
        stop_serving(self._running, self._slot, self._threads, self._tcp, self._udp)
        log.info("gripper server stopped")

    # -- TCP side -----------------------------------------------------------------------------

    def claim(self, session: GripperSession) -> bool:
        """``session`` completed a valid Connect: may it hold the hand? (see ClientSlot)"""
        return self._slot.claim(session)

    def client_connected(self, session: GripperSession) -> None:
        addr = (session.peer[0], int(session.udp_port))
        self._post(lambda: setattr(self, "_client_addr", addr))

    def session_closed(self, session: GripperSession) -> None:
        if not self._slot.holds(session):
            self._slot.release(session)  # it never connected: nothing to undo
            return
        log.info("gripper client %s disconnected", session.peer)

        def forget() -> None:
            self._client_addr = None
            self._pending = {k: v for k, v in self._pending.items() if v[0] is not session}

        # Posted before the slot frees, so it runs before the next client's Connect.
        self._post(forget)
        self._slot.release(session)

    def submit(self, session: GripperSession, command: Command, command_id: int, args) -> None:
        """Apply a decoded request on the timer thread (the reader never waits for it)."""

        def apply() -> None:
            try:
                self._apply(session, command, command_id, args)
            except Exception:  # every request is answered: libfranka has no reply timeout
                log.exception("gripper %s (id %d) failed; answered kFail", command.name, command_id)
                session.reply(command, command_id, Status.kFail)

        self._post(apply)

    def _apply(self, session: GripperSession, command: Command, command_id: int, args) -> None:
        hand = self.hand
        try:
            if command == Command.kHoming:
                action = hand.homing()
            elif command == Command.kMove:
                width, speed = args
                action = hand.move(width, speed)
            elif command == Command.kGrasp:
                width, eps_inner, eps_outer, speed, force = args
                action = hand.grasp(width, speed, force, eps_inner, eps_outer)
            else:  # kStop: halts in place; the interrupted command is answered below
                hand.stop()
                self._answer_finished()
                session.reply(command, command_id, Status.kSuccess)
                return
        except ValueError as exc:
            # A command the hand cannot execute: kFail, libfranka raises
            # CommandException "Command failed!" (docs/fci-behaviour.md "Command coverage").
            log.warning(
                "gripper client %s: invalid-argument in %s (id %d): %s: answered kFail",
                session.peer,
                command.name,
                command_id,
                exc,
            )
            session.reply(command, command_id, Status.kFail)
            return
        self._answer_finished()  # a command preempted by this one
        self._pending[action] = (session, command, command_id)

    def _answer_finished(self) -> None:
        for action, outcome in self.hand.take_finished():
            entry = self._pending.pop(action, None)
            if entry is None:
                continue
            session, command, command_id = entry
            # A Stop aborts the running Grasp/Move: we answer it kAborted. What the
            # real hand answers here (kAborted or kUnsuccessful) is not documented
            # (docs/wire-protocol.md §10.2).
            session.reply(command, command_id, _STATUS_OF[outcome])

    # -- the timer ----------------------------------------------------------------------------

    def _post(self, apply) -> None:
        """Hand a request to the timer thread and wake it."""
        self._requests.put(apply)
        self._wake.set()

    def _timer_loop(self) -> None:
        """Step the hand at 250 Hz while the fingers move, else only as often as the
        60 Hz broadcast needs (and not at all with no client), so an idle gripper
        server costs the robot's 1 kHz tick nothing; a request wakes it at once."""
        dt = 1.0 / STEP_HZ
        last = next_broadcast = time.perf_counter()
        while self._running.is_set():
            apply_pending(self._requests, log, "gripper request")
            now = time.perf_counter()
            self.hand.step(min(now - last, 0.1))  # the model moves by the time that passed
            last = now
            self._answer_finished()
            if now >= next_broadcast:
                next_broadcast = max(next_broadcast + 1.0 / BROADCAST_HZ, now - 0.1)
                self._broadcast()
            if self.hand.busy:
                timeout = dt
            elif self._client_addr is not None:
                timeout = max(0.0, next_broadcast - time.perf_counter())
            else:
                timeout = 0.1
            self._wake.wait(timeout)
            self._wake.clear()

    def _broadcast(self) -> None:
        """§10.3 GripperState; message_id is this loop's counter (seed)."""
        self._message_id = (self._message_id + 1) & 0xFFFFFFFF
        addr = self._client_addr
        if addr is None:
            return
        state = self._state[0]
        state["message_id"] = self._message_id
        state["width"] = self.hand.width
        state["max_width"] = self.hand.max_width
        state["is_grasped"] = self.hand.is_grasped
        state["temperature"] = TEMPERATURE_C
        try:
            self._udp.sendto(self._state.tobytes(), addr)
        except OSError as exc:
            self._udp_log.warning("udp-send-failed", "gripper state not sent to %s: %s", addr, exc)


_STATUS_OF = {
    Outcome.SUCCESS: Status.kSuccess,
    Outcome.UNSUCCESSFUL: Status.kUnsuccessful,
    Outcome.ABORTED: Status.kAborted,
}
