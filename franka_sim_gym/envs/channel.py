"""Channel models: which RobotCommand datagrams reach the robot, and when (in cycles).

In socket mode the real network decides; in-process the env's channel does, so
lost cycles, extrapolation, late datagrams and communication_constraints_violation
happen exactly as over a bad link (architecture.md: "A new way to deliver
commands ... envs/channel.py, never the controller"). Every model is seeded
through the env's RNG, so an episode is reproducible from ``reset(seed=...)``.

A channel takes the command sent in cycle k and returns the list of commands
delivered in cycle k (possibly older ones, delayed), oldest first: late
datagrams then go through the controller's late-datagram path.
"""

from __future__ import annotations

import copy
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from .. import native
from ..reality import stream
from ..reality.ahead import Ahead

#: the lost-cycle run law's one text, the controller's (fci/_accounting.c lost_runs)
_LOST_RUNS = native.require("fci._accounting", "lost_runs").lost_runs


class Channel:
    """A perfect link: every command arrives in the cycle it was sent."""

    def reset(self, rng: np.random.Generator) -> None:
        """Start a new episode with the env's RNG."""
        self.rng = rng

    def transmit(self, command: np.ndarray) -> list[np.ndarray]:
        """The commands delivered this cycle, given the one sent now (oldest first)."""
        return [command]


@dataclass
class BernoulliLoss(Channel):
    """Each datagram is lost independently with probability ``p``."""

    p: float = 0.01

    def __post_init__(self) -> None:
        if not 0.0 <= self.p <= 1.0:
            raise ValueError(f"BernoulliLoss: p must be in [0, 1], got {self.p}")

    def transmit(self, command: np.ndarray) -> list[np.ndarray]:
        return [] if self.rng.random() < self.p else [command]


@dataclass
class GilbertElliott(Channel):
    """Bursty loss: a two-state Markov chain (good / bad) with a loss rate per state.

    Args:
        p_good_to_bad: probability per cycle of entering the bad state.
        p_bad_to_good: probability per cycle of leaving it (mean burst 1/p cycles).
        loss_good, loss_bad: loss probability in each state.
    """

    p_good_to_bad: float = 0.002
    p_bad_to_good: float = 0.1
    loss_good: float = 0.0
    loss_bad: float = 0.9
    _bad: bool = field(default=False, init=False, repr=False)

    def __post_init__(self) -> None:
        for name in ("p_good_to_bad", "p_bad_to_good", "loss_good", "loss_bad"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise ValueError(f"GilbertElliott: {name} must be in [0, 1], got {value}")

    def reset(self, rng: np.random.Generator) -> None:
        super().reset(rng)
        self._bad = False

    def transmit(self, command: np.ndarray) -> list[np.ndarray]:
        u = self.rng.random(2)
        self._bad = (u[0] >= self.p_bad_to_good) if self._bad else (u[0] < self.p_good_to_bad)
        loss = self.loss_bad if self._bad else self.loss_good
        return [] if u[1] < loss else [command]


@dataclass
class Delay(Channel):
    """Every datagram arrives ``cycles`` cycles late, or a random 0..``max_cycles`` late.

    Delayed datagrams keep their order (a FIFO link); with ``max_cycles`` set each
    datagram's delay is drawn uniformly, and one that would overtake an earlier one
    waits for it.
    """

    cycles: int = 1
    max_cycles: int | None = None
    _queue: deque = field(default_factory=deque, init=False, repr=False)
    _now: int = field(default=0, init=False, repr=False)

    def __post_init__(self) -> None:
        if self.cycles < 0 or (self.max_cycles is not None and self.max_cycles < 0):
            raise ValueError("Delay: cycles must be >= 0")

    def reset(self, rng: np.random.Generator) -> None:
        super().reset(rng)
        self._queue = deque()
        self._now = 0

    def transmit(self, command: np.ndarray) -> list[np.ndarray]:
        delay = self.cycles
        if self.max_cycles is not None:
            delay = int(self.rng.integers(0, self.max_cycles + 1))
        due = self._now + delay
        if self._queue:
            due = max(due, self._queue[-1][0])  # FIFO: never overtake
        self._queue.append((due, command.copy()))
        delivered = []
        while self._queue and self._queue[0][0] <= self._now:
            delivered.append(self._queue.popleft()[1])
        self._now += 1
        return delivered


def make_channel(spec: Channel | str | None) -> Channel:
    """A channel from an instance, None (perfect), or a short spec such as ``"loss:0.01"``,
    ``"bursty"``, ``"delay:2"``, ``"delay:0-3"``."""
    if spec is None or spec == "none":
        return Channel()
    if isinstance(spec, Channel):
        return spec
    name, _, arg = str(spec).partition(":")
    if name == "loss":
        return BernoulliLoss(float(arg or 0.01))
    if name == "bursty":
        return GilbertElliott()
    if name == "delay":
        if "-" in arg:
            lo, hi = arg.split("-")
            if int(lo) != 0:
                raise ValueError("delay:A-B: random delays start at 0 cycles (delay:0-B)")
            return Delay(max_cycles=int(hi))
        return Delay(cycles=int(arg or 1))
    raise ValueError(f"unknown channel {spec!r}: expected none, loss:P, bursty, delay:N, delay:0-N")


class Links:
    """The links of n arms: one channel each, the lost cycles they cause, and the
    delivery of each arm's datagrams to the controller in their own order.

    ``perfect``: every link is a plain ``Channel`` (the core then hands commands to the
    controller itself, one call for all arms)."""

    def __init__(self, spec, n: int, drawn: bool = False) -> None:
        self.channels = per_arm_channels(spec, n)
        self.perfect = all(type(c) is Channel for c in self.channels)
        self.n = n
        #: the links of a reality profile's draws (None: the channels above decide)
        self.drawn: DrawnLinks | None = None
        if drawn:
            if not self.perfect:
                raise ValueError(
                    "channel and reality's communication both model the link: give one "
                    "(a reality profile whose communication is perfect, or channel=None)"
                )
            self.drawn = DrawnLinks(n)
            self.perfect = False
            self.transmit = self._transmit_drawn  # (a cycle's one call on this path)
        #: per arm: the robot answers every cycle itself (the asynchronous generator,
        #: docs/motion-limits.md): a datagram the link drops is a target late, no lost cycle
        self.robot_answers = np.zeros(n, dtype=bool)
        #: per arm: the current and the longest run of consecutive lost cycles
        self.lost_run = np.zeros(n, dtype=np.int64)
        self.longest_lost = np.zeros(n, dtype=np.int64)
        self._rounds: list[np.ndarray] = []  # the k-th datagram delivered to each arm
        self._in_run = False  # some arm's run of lost cycles is open

    def reset(self, arms: np.ndarray, rngs: list) -> None:
        """New episodes on ``arms`` (arm i's channel draws from ``rngs[i]``)."""
        for i in arms.tolist():
            self.channels[i].reset(rngs[i])
        self.lost_run[arms] = 0
        self.longest_lost[arms] = 0
        self._in_run = bool(self.lost_run.any())

    def begin_step(self, cycles: int) -> None:
        """A policy step of ``cycles`` cycles begins (the drawn links draw them at once)."""
        if self.drawn is not None:
            self.drawn.begin_step(cycles)

    def transmit(self, command: np.ndarray, sending: np.ndarray, lost: np.ndarray, receive) -> None:
        """Send ``command`` (n rows) of the ``sending`` arms through their channels and
        hand what arrives to ``receive(batch, mask)`` (the controller's), round by round;
        count in ``lost`` the cycles no command answered in time."""
        n = self.n
        open_ids = command["message_id"].copy()
        answered = np.zeros(n, dtype=bool)
        rounds: list[list[tuple[int, np.ndarray]]] = []
        for i in np.flatnonzero(sending).tolist():
            for r, delivered in enumerate(self.channels[i].transmit(command[i : i + 1])):
                if r == len(rounds):
                    rounds.append([])
                rounds[r].append((i, delivered))
        for r, deliveries in enumerate(rounds):
            if r == len(self._rounds):
                self._rounds.append(np.zeros(n, dtype=command.dtype))
            batch, mask = self._rounds[r], np.zeros(n, dtype=bool)
            for i, delivered in deliveries:
                batch[i] = delivered[0]
                mask[i] = True
                answered[i] |= bool(delivered["message_id"][0] == open_ids[i])
            receive(batch, mask)
        self._account(sending, answered, lost)

    def _transmit_drawn(self, command, sending, lost, receive) -> None:
        """:meth:`transmit` through the drawn links: the datagrams that reach the robot in
        their cycle go in one batch; the others answer nothing (the robot drops what misses
        its window: :class:`DrawnLinks`)."""
        drawn = self.drawn
        k = drawn.k
        drawn.k = k + 1
        drops = drawn.drops
        if drops is None or not drops[k]:  # every sending arm's datagram arrives in time
            receive(command, sending)
            if self._in_run:
                self._account(sending, sending, lost)
            return
        delivered = sending & ~drawn.blocked[k]
        receive(command, delivered)
        self._account(sending, delivered, lost)

    def _account(self, sending, answered, lost) -> None:
        # A cycle is lost when no command answering it reached the robot in time (and the
        # robot does not answer it itself): the controller's run law (fci/_accounting.c).
        self._in_run = _LOST_RUNS(
            sending, answered, self.robot_answers, lost, self.lost_run, self.longest_lost
        )


class DrawnLinks:
    """The links of n arms under a reality profile's communication (docs/reality.md):
    each episode arm i loses a command datagram with its drawn probability ``loss``, and
    with probability ``jitter`` a datagram is held up by 1 to ``jitter_cycles`` cycles
    (uniformly) with the ones sent behind it (first in, first out: a spike of d cycles
    holds up the datagrams of d cycles). A held-up datagram reaches the robot after its
    1 ms window, and the FCI drops a command that missed its window (the seed's "A
    datagram that turns up late replaces the guess it stood in for": the sim's server
    applies one, a deliberate departure for clients that are not real-time; a link that
    models the robot's own network hands the controller only what the robot would take):
    each such cycle is lost. Every arm's decisions of a cycle are one lookup (its own
    stream, drawn ahead: reality/ahead.py).

    Args:
        n: arms.
    """

    def __init__(self, n: int) -> None:
        # per arm, the odds of a loss and of a spike, one row against a cycle's two draws
        self._odds = np.zeros((n, 2))
        self.loss = self._odds[:, 0]
        self.jitter = self._odds[:, 1]
        self.cycles = np.ones(n, dtype=np.int64)
        self.ahead = Ahead(n, 2, lambda rng, i, count: rng.random((count, 2)))
        #: per arm, the first cycle whose datagram is not held up behind a spike
        self._free = np.zeros(n, dtype=np.int64)
        self._now = 0
        #: this step's table (begin_step): which arm's datagram each cycle drops, whether
        #: the cycle drops any (None: no cycle does), and the cycles transmitted so far
        self.blocked: np.ndarray | None = None
        self.drops: list[bool] | None = None
        self._frees: np.ndarray | None = None
        self.k = 0

    def apply(self, arms, draws) -> None:
        """New episodes on ``arms`` with their draws (rows of a reality DrawBatch)."""
        arms = np.atleast_1d(np.asarray(arms, dtype=np.intp))
        self.loss[arms] = draws["communication.loss"]
        self.jitter[arms] = draws["communication.jitter"]
        self.cycles[arms] = draws["communication.jitter_cycles"].astype(np.int64)
        self.ahead.reseed(arms, [stream(d.seed, "communication") for d in draws.draws])
        self._settle()
        self._free[arms] = self._now

    def begin_step(self, cycles: int) -> None:
        """The losses and spikes of the next ``cycles`` cycles of every arm, drawn at once
        (the streams move on by ``cycles`` whether or not all of them are used), and which
        arm's datagram each of those cycles drops: ``blocked[k]`` ((n,) bool), read by
        :meth:`Links.transmit` (which moves ``k`` on) where ``drops[k]`` says cycle k drops
        any (``drops`` None: no cycle of the step does)."""
        self._settle()
        u = self.ahead.take(cycles)
        events = u < self._odds  # (cycles, n, 2): a loss, a spike
        if not events.any() and int(self._free.max()) <= self._now:
            # A quiet step (most are): nothing drops and nothing is held up after it.
            self.drops = None
            self._frees = None
            return
        lost, spike = events[..., 0], events[..., 1]
        # u / jitter is uniform in [0, 1) given u < jitter: a spike of 1 to cycles cycles,
        # holding up the datagrams until the cycle ``ends`` (the later of overlapping ones)
        ratio = np.divide(u[..., 1], self.jitter, out=np.zeros(u.shape[:2]), where=spike)
        now = self._now + np.arange(cycles)[:, None]
        ends = np.where(spike, now + 1 + (ratio * self.cycles).astype(np.int64), 0)
        ends[0] = np.maximum(ends[0], self._free)
        self._frees = np.maximum.accumulate(ends, axis=0)
        blocked = lost | (self._frees > now)
        self.blocked = blocked
        self.drops = blocked.any(axis=1).tolist()

    def _settle(self) -> None:
        """Move the clock and the held-up datagrams' end on by the cycles the last step
        transmitted (a step can end before its last cycle)."""
        if self.k:
            if self._frees is not None:
                self._free = self._frees[self.k - 1].copy()
            self._now += self.k
            self.k = 0


def per_arm_channels(spec, n: int) -> list[Channel]:
    """One channel per arm from a spec (``make_channel``'s, or an instance: copied per arm,
    so that every arm has its own link and random stream) or a list of n of them."""
    if isinstance(spec, (list, tuple)):
        if len(spec) != n:
            raise ValueError(f"channel: a list needs one entry per arm ({n}), got {len(spec)}")
        channels = [make_channel(s) for s in spec]
    else:
        channel = make_channel(spec)
        channels = [channel] + [copy.deepcopy(channel) for _ in range(n - 1)]
    if len({id(c) for c in channels}) != n:
        raise ValueError("channel: every arm needs a Channel instance of its own")
    return channels
