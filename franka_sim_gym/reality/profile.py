"""A reality profile: how the simulated robot differs from its own model and from ideal
sensors, as values or as ranges drawn per episode (docs/reality.md).

A profile is a nested mapping of five sections, every entry optional (a missing entry
is the ideal robot's, or its ``base`` profile's)::

    {"base": "fr3",                                  # start from a shipped profile
     "model": {"mass_scale": {"uniform": [0.95, 1.05]}},
     "sensors": {"tau_J_noise": 0.005},
     "communication": {"loss": 0.001}}

An entry is a number (every element of the entry's shape), a list of the entry's shape,
or ``{"uniform": [low, high]}`` (low and high each a number or a list of the shape): a
value drawn uniformly per element and per episode. :data:`ENTRIES` lists every entry
with its shape, its bound and what it means. A bad profile -- an unknown key, a value out
of its bound (a negative noise, a mass scale <= 0), a wrong shape, ``low > high`` -- is a
ValueError naming the entry.
"""

from __future__ import annotations

import copy
import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

import numpy as np


@dataclass(frozen=True)
class Entry:
    """One entry of a profile: its shape, the bound its values keep, its ideal value."""

    shape: tuple[int, ...]
    #: "positive" (> 0), "nonnegative" (>= 0), "probability" ([0, 1]), "cycles" (a whole
    #: number >= 1) or "any" (finite)
    bound: str
    #: the ideal robot's value (the physics is the model, the sensors are exact)
    ideal: float
    unit: str
    doc: str


#: Every entry of a profile, by section (docs/reality.md explains each and cites its
#: sources). Links and joints are the arm's 1..7.
ENTRIES: Mapping[str, Mapping[str, Entry]] = MappingProxyType(
    {
        "model": {
            "mass_scale": Entry((7,), "positive", 1.0, "", "link mass: the arm's / the model's"),
            "com_offset": Entry(
                (7, 3), "any", 0.0, "m", "centre of mass: the arm's - the model's (link frame)"
            ),
        },
        "friction": {
            "scale": Entry(
                (7,), "nonnegative", 0.0, "", "joint friction in the drives / Gaz et al.'s"
            ),
            "compensation": Entry(
                (7,), "nonnegative", 0.0, "", "the robot's friction compensation / Gaz et al.'s"
            ),
        },
        "sensors": {
            "tau_J_noise": Entry((7,), "nonnegative", 0.0, "Nm", "tau_J's noise (std)"),
            "tau_J_offset": Entry((7,), "any", 0.0, "Nm", "tau_J's offset (per episode)"),
            "q_noise": Entry((7,), "nonnegative", 0.0, "rad", "q's noise (std)"),
            "dq_noise": Entry((7,), "nonnegative", 0.0, "rad/s", "dq's noise (std)"),
        },
        "scene": {
            "object_mass_scale": Entry((), "positive", 1.0, "", "scene objects' mass / nominal"),
            "object_friction_scale": Entry(
                (), "positive", 1.0, "", "scene objects' sliding friction / nominal"
            ),
            "table_height": Entry((), "any", 0.0, "m", "the table's surface above the base plane"),
            "fixture_offset": Entry(
                (2,), "any", 0.0, "m", "a fixture's x, y offset from where the task put it"
            ),
        },
        "communication": {
            "loss": Entry((), "probability", 0.0, "", "a command datagram is lost"),
            "jitter": Entry((), "probability", 0.0, "", "a command datagram arrives late"),
            "jitter_cycles": Entry((), "cycles", 3.0, "cycles", "the latest a late one arrives"),
        },
    }
)

#: The sections of a profile, in the order they are drawn.
SECTIONS = tuple(ENTRIES)


@dataclass(frozen=True, eq=False)
class RealityProfile:
    """A validated profile: for every entry the low and high ends of its range (equal
    for a fixed value), each an array of the entry's shape (read-only).

    Build one with :func:`load_profile` (a shipped name, a dict, a JSON file).
    """

    name: str
    low: Mapping[str, np.ndarray]
    high: Mapping[str, np.ndarray]

    @property
    def is_ideal(self) -> bool:
        """Every entry fixed at the ideal robot's value: the physics is the model, the
        sensors are exact, the link is perfect (the simulation runs as without one)."""
        return ideal_sections(self.low, SECTIONS) and ideal_sections(self.high, SECTIONS)

    @property
    def scene_is_ideal(self) -> bool:
        """The scene section is the task's in every episode."""
        return ideal_sections(self.low, ("scene",)) and ideal_sections(self.high, ("scene",))

    @property
    def link_is_ideal(self) -> bool:
        """The communication section is the perfect link's in every episode."""
        sections = ("communication",)
        return ideal_sections(self.low, sections) and ideal_sections(self.high, sections)

    @property
    def randomized(self) -> tuple[str, ...]:
        """The entries drawn per episode (low < high somewhere)."""
        return tuple(k for k, _ in entries() if np.any(self.low[k] != self.high[k]))

    def spec(self) -> dict:
        """The profile as a mapping :func:`load_profile` reads back to the same profile."""
        out: dict = {section: {} for section in SECTIONS}
        for key, _ in entries():
            section, name = key.split(".")
            low, high = self.low[key], self.high[key]
            value = (
                low.tolist()
                if np.array_equal(low, high)
                else {"uniform": [low.tolist(), high.tolist()]}
            )
            out[section][name] = value
        return out

    def __repr__(self) -> str:
        return f"RealityProfile({self.name!r}, randomized={list(self.randomized)})"

    def __deepcopy__(self, memo: dict) -> RealityProfile:
        return self  # immutable

    def __reduce__(self):
        return _restore, (self.name, dict(self.low), dict(self.high))


def _restore(name: str, low: dict, high: dict) -> RealityProfile:
    """A pickled profile, as it was (its name kept, its arrays read-only)."""
    for values in (low, high):
        for array in values.values():
            array.flags.writeable = False
    return RealityProfile(name, MappingProxyType(low), MappingProxyType(high))


#: The sections of the robot and its world (the rest is the link's).
ROBOT_SECTIONS = ("model", "friction", "sensors", "scene")


def ideal_sections(values: Mapping[str, np.ndarray], sections) -> bool:
    """Whether ``values`` (by entry) are the ideal robot's in ``sections`` (a link that
    delays nothing has no latest delay to speak of)."""
    for key, entry in entries():
        section, name = key.split(".")
        if section not in sections:
            continue
        if name == "jitter_cycles" and np.all(values["communication.jitter"] == 0.0):
            continue
        if not np.all(values[key] == entry.ideal):
            return False
    return True


def entries():
    """(``"section.name"``, :class:`Entry`) for every entry, in drawing order."""
    for section, names in ENTRIES.items():
        for name, entry in names.items():
            yield f"{section}.{name}", entry


def load_profile(profile: str | Path | Mapping | RealityProfile | None) -> RealityProfile:
    """A profile from a shipped name ("ideal", "fr3", "randomized"), a JSON file's path or
    a JSON object's text, a mapping (see the module docstring), or a profile; None is
    "ideal".

    Raises:
        ValueError: an unknown name or key, a file that is not a JSON object, a value
            out of its bound or of the wrong shape; the message names the entry.
    """
    from .shipped import PROFILES  # the shipped profiles are written as mappings

    if isinstance(profile, RealityProfile):
        return profile
    if profile is None:
        profile = "ideal"
    name = "custom"
    if isinstance(profile, (str, Path)):
        text = str(profile)
        if isinstance(profile, str) and text in PROFILES:
            name, profile = text, PROFILES[text]
        elif isinstance(profile, str) and text.lstrip().startswith("{"):
            try:
                profile = json.loads(text)
            except json.JSONDecodeError as exc:
                raise ValueError(f"reality profile {text!r}: not JSON ({exc})") from None
        elif Path(text).is_file():
            name = Path(text).stem
            try:
                profile = json.loads(Path(text).read_text(encoding="utf-8"))
            except json.JSONDecodeError as exc:
                raise ValueError(f"reality profile {text!r}: not JSON ({exc})") from None
        else:
            names = ", ".join(PROFILES)
            raise ValueError(
                f"reality profile {text!r}: neither a shipped profile ({names}) nor a file"
            )
    if not isinstance(profile, Mapping):
        raise ValueError(f"reality profile: expected a mapping, got {type(profile).__name__}")
    return _build(name, _resolve(profile, PROFILES, ()))


def _resolve(spec: Mapping, shipped: Mapping, seen: tuple) -> dict:
    """``spec`` with its ``base`` (a shipped profile's name) merged under it, entry by
    entry."""
    spec = copy.deepcopy(dict(spec))
    base = spec.pop("base", None)
    if base is None:
        return spec
    if not isinstance(base, str) or base not in shipped:
        raise ValueError(
            f"reality profile: base {base!r} is not a shipped profile ({list(shipped)})"
        )
    if base in seen:
        raise ValueError(f"reality profile: base {base!r} refers back to itself")
    merged = _resolve(shipped[base], shipped, (*seen, base))
    for section, values in spec.items():
        if isinstance(values, Mapping) and isinstance(merged.get(section), Mapping):
            merged[section] = {**merged[section], **values}
        else:
            merged[section] = values
    return merged


def _build(name: str, spec: Mapping) -> RealityProfile:
    unknown = [k for k in spec if k not in ENTRIES]
    if unknown:
        raise ValueError(
            f"reality profile: unknown section(s) {unknown} (expected some of {list(SECTIONS)})"
        )
    low: dict[str, np.ndarray] = {}
    high: dict[str, np.ndarray] = {}
    for section, names in ENTRIES.items():
        values = spec.get(section, {})
        if not isinstance(values, Mapping):
            raise ValueError(f"reality profile: section {section!r} must be a mapping")
        unknown = [k for k in values if k not in names]
        if unknown:
            raise ValueError(
                f"reality profile: unknown key(s) {[f'{section}.{k}' for k in unknown]} "
                f"(expected some of {[f'{section}.{k}' for k in names]})"
            )
        for key, entry in names.items():
            lo, hi = _range(f"{section}.{key}", entry, values.get(key, entry.ideal))
            low[f"{section}.{key}"], high[f"{section}.{key}"] = lo, hi
    return RealityProfile(name, MappingProxyType(low), MappingProxyType(high))


def _range(key: str, entry: Entry, value) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) of one entry, each of the entry's shape, read-only, checked."""
    if isinstance(value, Mapping):
        if set(value) != {"uniform"}:
            raise ValueError(
                f"reality profile: {key}: a range is {{'uniform': [low, high]}}, got {dict(value)}"
            )
        pair = value["uniform"]
        if not isinstance(pair, (list, tuple)) or len(pair) != 2:
            raise ValueError(f"reality profile: {key}: 'uniform' takes [low, high], got {pair!r}")
        lo, hi = (_array(key, entry, v) for v in pair)
        if np.any(lo > hi):
            raise ValueError(f"reality profile: {key}: low {lo.tolist()} > high {hi.tolist()}")
    else:
        lo = hi = _array(key, entry, value)
    return lo, hi


def _array(key: str, entry: Entry, value) -> np.ndarray:
    try:
        array = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(
            f"reality profile: {key}: not a number or a list of them: {value!r}"
        ) from None
    if array.shape != entry.shape:
        if array.ndim == 0:
            array = np.full(entry.shape, float(array))
        else:
            raise ValueError(
                f"reality profile: {key}: expected a number or shape {entry.shape}, "
                f"got shape {array.shape}"
            )
    problem = _out_of_bound(entry.bound, array)
    if problem:
        raise ValueError(f"reality profile: {key} {problem}, got {array.tolist()}")
    array.flags.writeable = False
    return array


def _out_of_bound(bound: str, array: np.ndarray) -> str | None:
    if not np.all(np.isfinite(array)):
        return "must be finite"
    if bound == "positive" and np.any(array <= 0):
        return "must be > 0"
    if bound == "nonnegative" and np.any(array < 0):
        return "must be >= 0"
    if bound == "probability" and np.any((array < 0) | (array > 1)):
        return "must be in [0, 1]"
    if bound == "cycles" and np.any((array < 1) | (array != np.floor(array))):
        return "must be a whole number of cycles >= 1"
    return None


def as_number(value: np.ndarray):
    """A drawn entry as plain Python numbers (a float, or nested lists)."""
    return float(value) if value.ndim == 0 else value.tolist()
