"""Reality profiles: how the simulated robot differs from its own model, from ideal
sensors and from a perfect link, drawn per episode from a seeded generator
(docs/reality.md).

The physics holds the true arm and world (``franka_sim_gym.sim``: masses,
friction in the drives, objects); the controller holds the robot's own model and what
its sensors report (``franka_sim_gym.fci``); the env's channel the link. One draw is
given to all of them. numpy only: every layer may import it.
"""

from .draw import DrawBatch, RealityDraw, draw, episode_seed, stream, streams
from .profile import ENTRIES, SECTIONS, RealityProfile, load_profile
from .shipped import PROFILES

__all__ = [
    "ENTRIES",
    "PROFILES",
    "SECTIONS",
    "DrawBatch",
    "RealityDraw",
    "RealityProfile",
    "draw",
    "episode_seed",
    "load_profile",
    "stream",
    "streams",
]
