"""The FCI robot server: one tick thread owns the controller and the 1 kHz state stream.

Threads (architecture.md "The two clocks"):

* the tick thread waits for each millisecond boundary (with ``--lockstep``, during
  a motion, for the command answering the last state instead:
  :mod:`~franka_sim_gym.server.lockstep`), applies the TCP
  requests posted since the last tick, hands the command datagrams received
  since then to the controller, runs one cycle, sends the state, and then
  delivers the cycle's events (so a kReflexAborted is sent only after the
  state carrying the error), then runs the tick hooks (the physics gripper's
  finger drive: all MuJoCo access stays on this thread);
* an accept thread, and per connection a reader thread (requests in) and an
  outbox thread (replies out): the tick thread only queues a reply, so a client
  that stops reading never holds up the robot; it is dropped once past the
  outbox's bounds (:mod:`~franka_sim_gym.server.outbox`). The connection that
  completes a valid Connect holds the robot (:mod:`~franka_sim_gym.server.client_slot`).

No rule of the robot lives here: the server only delivers datagrams, requests
and the tick to ``franka_sim_gym.fci``.
"""

from __future__ import annotations

import dataclasses
import logging
import queue
import signal
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..fci.config import ControllerConfig
from ..fci.controller import FciController
from ..fci.events import EventKind
from ..fci.wire import ROBOT_COMMAND_DTYPE, ROBOT_COMMAND_SIZE
from ..fci.wire import protocol as p
from ..reality import DrawBatch, RealityDraw
from ..sim.arm import ArmPhysics
from ..sim.world import URDF_PATH
from .client_slot import ClientSlot, stop_serving
from .lockstep import DEFAULT_TIMEOUT_S, AnswerWait
from .logging_util import RateLimitedLog
from .pacing import next_tick
from .request_queue import apply_pending
from .session import ClientSession

log = logging.getLogger("franka_sim_gym.server")


@dataclass
class ServerOptions:
    """Where and how to serve."""

    host: str = "127.0.0.1"
    port: int = p.COMMAND_PORT
    urdf: Path | None = None
    visualize: bool = False
    #: during a motion, run each cycle as soon as the client answered (docs/socket.md)
    lockstep: bool = False
    #: in lockstep, how long a state waits for its answer before the cycle is lost [s]
    lockstep_timeout: float = DEFAULT_TIMEOUT_S
    #: the robot's draw of a reality profile (``serve --reality``, docs/reality.md);
    #: None: the ideal robot
    reality: RealityDraw | None = None


class RobotServer:
    """Serves one simulated FR3 to one libfranka client at a time.

    Args:
        config: the controller's switches (enforcement, robot tables, ...).
        options: bind address, port, URDF to serve, viewer.
        physics: the world to serve (default: one bare FR3); ``--gripper-physics``
            passes one with the hand mounted.
    """

    def __init__(
        self,
        config: ControllerConfig | None = None,
        options: ServerOptions | None = None,
        physics: ArmPhysics | None = None,
    ):
        self.config = config or ControllerConfig()
        self.options = options or ServerOptions()
        self.urdf = Path(self.options.urdf or URDF_PATH).read_text(encoding="utf-8")
        self.physics = physics or ArmPhysics(n_arms=1)
        self._tick_hooks: list[Callable[[], None]] = []
        self.controller = FciController(self.physics, self.config)
        if self.options.reality is not None:
            self._apply_reality(self.options.reality)
        self._requests: queue.SimpleQueue[Callable[[], None]] = queue.SimpleQueue()
        self._slot = ClientSlot("", lambda sock, peer: ClientSession(self, sock, peer))
        self._client_addr: tuple[str, int] | None = None
        self._pending_move: tuple[ClientSession, int] | None = None
        self._pending_recovery: tuple[ClientSession, int] | None = None
        self._running = threading.Event()
        self._threads: list[threading.Thread] = []
        self._udp_log = RateLimitedLog(log)
        self._command = np.zeros(1, dtype=ROBOT_COMMAND_DTYPE)
        self._mask = np.ones(1, dtype=bool)
        # Zero-copy views: datagrams are received straight into the command
        # array, and the state is sent straight from the controller's array.
        self._command_buffer = memoryview(self._command.view(np.uint8))
        self._receive_buffer = bytearray(4096)
        self._state_bytes = memoryview(self.controller.states.view(np.uint8))
        self.ticks = 0
        self._viewer = None
        self._answer_wait: AnswerWait | None = None

    def _apply_reality(self, draw: RealityDraw) -> None:
        """The served robot is ``draw``'s for the server's life (before any tick): its arm,
        sensors and model (docs/reality.md); logged whole."""
        ctrl = self.controller
        ctrl.apply_reality([0], DrawBatch.stack([draw]))
        ctrl.reset([0], self.physics.q[0].copy())  # the first state from the drawn robot
        log.info("reality: %s", draw.json())
        if not draw.link_is_ideal:
            log.info(
                "reality: the profile's communication (loss, jitter) is the env's channel "
                "model; over sockets the network between the client and this server is the link"
            )

    # -- lifecycle ----------------------------------------------------------------------------

    def start(self) -> None:
        """Bind the sockets and start the threads."""
        host, port = self.options.host, self.options.port
        self._tcp = socket.create_server((host, port), reuse_port=False)
        self._tcp.settimeout(0.2)
        self._udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._udp.bind((host, 0))
        self._udp.setblocking(False)
        if self.options.lockstep:
            self._answer_wait = AnswerWait(self._udp.fileno(), self.options.lockstep_timeout)
        self._running.set()
        accept = lambda: self._slot.accept_loop(self._tcp, self._running)  # noqa: E731
        for target, name in ((self._tick_loop, "fci-tick"), (accept, "fci-accept")):
            thread = threading.Thread(target=target, name=name, daemon=True)
            thread.start()
            self._threads.append(thread)
        log.info(
            "serving FR3 FCI v%d on %s:%d (enforce motion limits: %s, comm constraints: %s, "
            "clock: %s)",
            p.VERSION,
            host,
            port,
            self.config.enforce_motion_limits,
            self.config.enforce_comm_constraints,
            (
                f"lockstep during motions, {self.options.lockstep_timeout * 1e3:g} ms for an answer"
                if self.options.lockstep
                else "1 kHz"
            ),
        )

    def stop(self) -> None:
        """Stop the threads and close every socket."""
        stop_serving(self._running, self._slot, self._threads, self._tcp, self._udp)
        if self._answer_wait is not None:
            self._answer_wait.close()
        if self._viewer is not None:
            self._viewer.close()
        log.info("server stopped")

    def serve_forever(self) -> None:
        """Start and block until interrupted (Ctrl-C exits cleanly)."""
        self.start()
        try:
            while self._running.is_set():
                time.sleep(0.2)
        except KeyboardInterrupt:
            log.info("interrupted")
        finally:
            # A second Ctrl-C must not interrupt the shutdown itself.
            signal.signal(signal.SIGINT, signal.SIG_IGN)
            self.stop()

    def add_tick_hook(self, hook: Callable[[], None]) -> None:
        """Run ``hook()`` on the tick thread after every cycle (call before :meth:`start`).

        A hook may read and write the MuJoCo world (it runs between two steps,
        on the thread that steps it); it must be short: it is inside the 1 ms cycle.
        """
        self._tick_hooks.append(hook)

    # -- TCP side -----------------------------------------------------------------------------

    def claim(self, session: ClientSession) -> bool:
        """``session`` completed a valid Connect: may it hold the robot? (see ClientSlot)"""
        return self._slot.claim(session)

    def client_connected(self, session: ClientSession) -> None:
        """Connect succeeded: stream states to (peer IP, UDP port from Connect)."""
        addr = (session.peer[0], int(session.udp_port))
        self._post(lambda: setattr(self, "_client_addr", addr))

    def session_closed(self, session: ClientSession) -> None:
        """A connection ended; if it held the robot, reset it to a clean idle for the next."""
        if not self._slot.holds(session):
            self._slot.release(session)  # it never connected: nothing to undo
            return
        log.info("client %s disconnected", session.peer)

        def reset() -> None:
            self._client_addr = None
            if self._pending_move and self._pending_move[0] is session:
                self._pending_move = None
            if self._pending_recovery and self._pending_recovery[0] is session:
                self._pending_recovery = None
            self.controller.end_session(0)

        # Posted before the slot frees, so it runs before the next client's Connect
        # is applied: a client that reconnects at once is never refused.
        self._post(reset)
        self._slot.release(session)

    def submit_request(self, session: ClientSession, command: p.Command, command_id: int, request):
        """Apply ``request`` on the tick thread at the next cycle boundary, then answer it.

        Every request is answered: libfranka has no reply timeout, so a handler
        that failed still answers (status 1, "not possible") and logs why.
        """

        def apply() -> None:
            try:
                self._apply(session, command, command_id, request)
            except Exception:
                log.exception("%s (request %d) failed; answered status 1", command.name, command_id)
                session.reply(command, command_id, 1)

        self._post(apply)

    def _post(self, request: Callable[[], None]) -> None:
        """Queue ``request`` for the tick thread (and end a lockstep wait to apply it)."""
        self._requests.put(request)
        if self._answer_wait is not None:
            self._answer_wait.notify()

    def _apply(self, session: ClientSession, command: p.Command, command_id: int, request) -> None:
        ctrl = self.controller
        C = p.Command
        if command == C.kMove:
            status = ctrl.move(
                0,
                request.controller_mode,
                request.motion_generator_mode,
                request.use_async_motion_generator,
                request.maximum_velocity,
            )
            # The preemption event of a running Move (if any) goes out first.
            self._deliver_events(ctrl.take_events())
            if status == p.MoveStatus.kMotionStarted:
                self._pending_move = (session, command_id)
            session.reply(command, command_id, status)
        elif command == C.kStopMove:
            status = ctrl.stop_move(0)
            session.reply(command, command_id, status)
        elif command == C.kAutomaticErrorRecovery:
            status = ctrl.automatic_error_recovery(0)
            if status is None:
                self._pending_recovery = (session, command_id)
            else:
                session.reply(command, command_id, status)
        elif command == C.kSetNEToEE:
            session.reply(command, command_id, ctrl.set_ne_to_ee(0, request.NE_T_EE))
        elif command == C.kSetEEToK:
            session.reply(command, command_id, ctrl.set_ee_to_k(0, request.EE_T_K))
        elif command == C.kSetLoad:
            status = ctrl.set_load(0, request.m_load, request.F_x_Cload, request.I_load)
            session.reply(command, command_id, status)
        elif command == C.kSetJointImpedance:
            session.reply(command, command_id, ctrl.set_joint_impedance(0, request.K_theta))
        elif command == C.kSetCartesianImpedance:
            status = ctrl.set_cartesian_impedance(0, request.K_x)
            session.reply(command, command_id, status)
        elif command == C.kSetCollisionBehavior:
            thresholds = {f.name: getattr(request, f.name) for f in dataclasses.fields(request)}
            status = ctrl.set_collision_behavior(0, thresholds)
            session.reply(command, command_id, status)
        elif command == C.kSetGuidingMode:
            status = ctrl.acknowledge_setter(0, "SetGuidingMode", [float(request.nullspace)])
            session.reply(command, command_id, status)
        else:  # pragma: no cover - every v10 command is handled above
            session.reply(command, command_id, 1)

    # -- the tick -----------------------------------------------------------------------------

    def _tick_loop(self) -> None:
        slot = time.perf_counter()
        wait = self._answer_wait
        while self._running.is_set():
            self._tick()
            if wait is not None and self._in_motion():
                wait.wait(
                    self._in_motion, self._answered, self._receive_datagrams, self._apply_requests
                )
                # Back on the 1 kHz clock, the next state leaves 1 ms after this cycle's.
                slot = time.perf_counter()
                continue
            now = time.perf_counter()
            wake, slot = next_tick(slot, now)
            if wake > now:
                time.sleep(wake - now)

    def _in_motion(self) -> bool:
        return self.controller.modes.n_motion > 0

    def _answered(self) -> bool:
        """Whether a command answering the last published state has arrived."""
        return bool(self.controller.accounting.answered[0])

    def _apply_requests(self) -> None:
        apply_pending(self._requests, log, "request")

    def _tick(self) -> None:
        self._apply_requests()
        self._receive_datagrams()
        events = self.controller.step()
        self.ticks += 1
        addr = self._client_addr
        if addr is not None:
            try:
                self._udp.sendto(self._state_bytes, addr)
            except OSError as exc:
                self._udp_log.warning("udp-send-failed", "state not sent to %s: %s", addr, exc)
        self._deliver_events(events)
        for hook in self._tick_hooks:
            hook()
        if self._viewer is not None and self.ticks % 16 == 0:
            self._viewer.sync()

    def _receive_datagrams(self) -> None:
        buffer = self._receive_buffer
        while True:
            try:
                size, addr = self._udp.recvfrom_into(buffer)
            except (BlockingIOError, InterruptedError):
                return
            except OSError as exc:  # e.g. ICMP port unreachable from a vanished client
                self._udp_log.warning("udp-receive-error", "%s", exc)
                continue
            client = self._client_addr
            if client is None or addr != client:
                self._udp_log.warning(
                    "datagram-from-unknown-address",
                    "ignored a %d-byte datagram from %s:%d (connected client: %s)",
                    size,
                    addr[0],
                    addr[1],
                    client,
                )
                continue
            if size != ROBOT_COMMAND_SIZE:
                self._udp_log.warning(
                    "datagram-wrong-size",
                    "ignored a %d-byte datagram from %s:%d: a RobotCommand is %d bytes",
                    size,
                    addr[0],
                    addr[1],
                    ROBOT_COMMAND_SIZE,
                )
                continue
            self._command_buffer[:] = buffer[:ROBOT_COMMAND_SIZE]
            self.controller.receive(self._command, self._mask)

    def _deliver_events(self, events) -> None:
        for event in events:
            if event.kind is EventKind.MOVE_FINISHED:
                log.info(
                    "motion ended: %s after %d cycles; lost %d (longest run %d)",
                    p.MoveStatus(event.status).name,
                    event.cycles,
                    event.lost_cycles,
                    event.longest_lost_run,
                )
                if self._answer_wait is not None:
                    log.info("%s", self._answer_wait.take_times().summary())
            if event.kind is EventKind.MOVE_FINISHED and self._pending_move is not None:
                session, command_id = self._pending_move
                self._pending_move = None
                session.reply(p.Command.kMove, command_id, event.status)
            elif event.kind is EventKind.RECOVERY_FINISHED and self._pending_recovery is not None:
                session, command_id = self._pending_recovery
                self._pending_recovery = None
                session.reply(p.Command.kAutomaticErrorRecovery, command_id, event.status)

    # -- viewer -------------------------------------------------------------------------------

    def open_viewer(self) -> None:
        """Open MuJoCo's passive viewer where a display exists; otherwise log why not."""
        import os

        if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            log.warning("--vis: no display ($DISPLAY unset); running without the viewer")
            return
        try:
            import mujoco.viewer

            self._viewer = mujoco.viewer.launch_passive(self.physics.model, self.physics.data)
        except Exception as exc:  # the viewer is optional; serving is not
            log.warning("--vis: could not open the MuJoCo viewer (%s)", exc)
