"""One episode's draw of a reality profile, and the seeds it is drawn from.

Every robot (every arm of a batch) draws its own values per episode from a generator
seeded by the episode's seed: the env derives that seed from the arm's random state at
reset (:func:`episode_seed`, which draws nothing from it, so the start pose and the goal
of an episode are the same whatever the profile), the server from ``--reality-seed``.
The same seed gives the same draw, and the same streams of sensor noise and of the
link's losses (:func:`streams`).
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from .profile import ROBOT_SECTIONS, SECTIONS, RealityProfile, as_number, entries, ideal_sections

#: The independent streams one seed feeds, by purpose (SeedSequence spawn keys).
STREAMS = ("draw", "sensors", "communication")


@dataclass(frozen=True, eq=False)
class RealityDraw:
    """What one robot is like for one episode: every entry of the profile drawn
    (``values["model.mass_scale"]`` is a (7,) array, read-only), and the seed of its
    noise and link streams.

    Immutable: a deep copy is the draw itself (the env's info carries it at every step).
    """

    profile: str
    seed: int
    values: Mapping[str, np.ndarray]

    def __getitem__(self, key: str) -> np.ndarray:
        return self.values[key]

    @property
    def robot_is_ideal(self) -> bool:
        """The arm is its model, its sensors exact, its world the task's (the link aside)."""
        return ideal_sections(self.values, ROBOT_SECTIONS)

    @property
    def scene_is_ideal(self) -> bool:
        """The scene is the task's."""
        return ideal_sections(self.values, ("scene",))

    @property
    def link_is_ideal(self) -> bool:
        """The link loses and delays nothing."""
        return ideal_sections(self.values, ("communication",))

    def as_dict(self) -> dict:
        """The drawn values by section, as plain numbers (what the server logs)."""
        out: dict = {"profile": self.profile, "seed": self.seed}
        for section in SECTIONS:
            out[section] = {}
        for key, value in self.values.items():
            section, name = key.split(".")
            out[section][name] = as_number(value)
        return out

    def __repr__(self) -> str:
        return f"RealityDraw({self.profile!r}, seed={self.seed})"

    def __deepcopy__(self, memo: dict) -> RealityDraw:
        return self

    def __eq__(self, other) -> bool:
        if not isinstance(other, RealityDraw):
            return NotImplemented
        return (self.profile, self.seed) == (other.profile, other.seed) and all(
            np.array_equal(v, other.values[k]) for k, v in self.values.items()
        )

    def __hash__(self) -> int:
        return hash((self.profile, self.seed))

    def json(self) -> str:
        """:meth:`as_dict` as one line of JSON (numbers rounded to 6 significant digits)."""
        return json.dumps(_rounded(self.as_dict()), separators=(",", ":"))


def _rounded(value):
    if isinstance(value, dict):
        return {k: _rounded(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_rounded(v) for v in value]
    if isinstance(value, float):
        return float(f"{value:.6g}")
    return value


def stream(seed: int, name: str) -> np.random.Generator:
    """The generator of one of a seed's purposes (``name`` in :data:`STREAMS`): child
    ``STREAMS.index(name)`` of the seed's SeedSequence, built alone (what
    ``SeedSequence(seed).spawn(3)[i]`` gives, without the other two)."""
    child = np.random.SeedSequence(int(seed), spawn_key=(STREAMS.index(name),))
    return np.random.Generator(np.random.PCG64(child))


def streams(seed: int) -> dict[str, np.random.Generator]:
    """The generators one seed feeds: the profile's draw, the sensors' noise, the link's
    losses and delays; independent of one another (SeedSequence children)."""
    return {name: stream(seed, name) for name in STREAMS}


def _plan() -> tuple[list[tuple[str, tuple, slice, bool]], int]:
    """Every entry's key, shape, slice of the draw's uniforms and whether it counts
    cycles, in drawing order; and the number of uniforms a draw takes."""
    plan, start = [], 0
    for key, entry in entries():
        size = math.prod(entry.shape)
        plan.append((key, entry.shape, slice(start, start + size), entry.bound == "cycles"))
        start += size
    return plan, start


_DRAW_PLAN, _DRAW_SIZE = _plan()


def draw(profile: RealityProfile, seed: int) -> RealityDraw:
    """The episode of seed ``seed``: every entry uniform in its range, element by
    element, in :func:`~franka_sim_gym.reality.profile.entries`'s order (a fixed entry
    is its value exactly)."""
    rng = stream(seed, "draw")
    # One call for every entry's uniforms: the same numbers, in the same order, as a
    # call per entry (each double takes the generator's next 64 bits).
    u = rng.random(_DRAW_SIZE)
    values = {}
    for key, shape, at, cycles in _DRAW_PLAN:
        low, high = profile.low[key], profile.high[key]
        value = np.where(low == high, low, low + (high - low) * u[at].reshape(shape))
        if cycles:
            value = np.floor(value)
        value = np.asarray(value, dtype=np.float64)
        value.flags.writeable = False
        values[key] = value
    return RealityDraw(profile.name, int(seed), MappingProxyType(values))


def episode_seed(rng: np.random.Generator) -> int:
    """A seed for the episode about to start on a robot whose random stream is ``rng``,
    read off its state (nothing is drawn from it): the same state gives the same seed,
    so a replayed or copied env, and arm i of a vector env seeded ``seed + i``, draw what
    a single env seeded alike draws."""
    digest = hashlib.sha256(_state_bytes(rng.bit_generator.state)).digest()
    return int.from_bytes(digest[:16], "little")


def _state_bytes(state) -> bytes:
    """A bit generator's state dict as bytes, in a fixed order."""
    if isinstance(state, Mapping):
        return (
            b"{"
            + b",".join(k.encode() + b":" + _state_bytes(state[k]) for k in sorted(state))
            + b"}"
        )
    if isinstance(state, np.ndarray):
        return state.dtype.str.encode() + state.tobytes()
    if isinstance(state, (list, tuple)):
        return b"[" + b",".join(_state_bytes(v) for v in state) + b"]"
    return repr(state).encode()


@dataclass(frozen=True)
class DrawBatch:
    """The draws of n robots stacked: ``values[key]`` is (n, *shape)."""

    draws: tuple[RealityDraw, ...]
    values: Mapping[str, np.ndarray]

    @classmethod
    def stack(cls, draws) -> DrawBatch:
        draws = tuple(draws)
        keys = draws[0].values.keys()
        return cls(draws, {k: np.stack([d.values[k] for d in draws]) for k in keys})

    def __getitem__(self, key: str) -> np.ndarray:
        return self.values[key]
