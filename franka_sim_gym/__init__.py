"""franka-sim-gym: the Franka FR3's FCI simulated on MuJoCo, for Gymnasium and libfranka clients."""

import logging

from . import envs as _envs  # noqa: F401  (registers the Gymnasium ids)

# A library logs, the application decides where it goes (the server configures
# logging; in the env every violation is also in ``info``).
logging.getLogger("franka_sim_gym").addHandler(logging.NullHandler())

__version__ = "0.1.0"
