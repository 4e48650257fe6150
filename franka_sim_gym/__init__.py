"""franka-sim-gym: the Franka FR3's FCI simulated on MuJoCo, for Gymnasium and libfranka clients."""

from . import envs as _envs  # noqa: F401  (registers the Gymnasium ids)

__version__ = "0.1.0"
