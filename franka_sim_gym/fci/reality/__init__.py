"""The robot under a reality draw: what its sensors report, and its friction compensation
(docs/reality.md).

The physics is the arm (sim/truth.py: its links' differences from the model, the friction
in its drives, its scene); this is what the robot makes of it:

* what its joint sensors report (sensors.py): noisy q, dq and tau_J, the state's fields
  that derive from them (theta, dtheta, dtau_J, the elbow; the estimate, the wrench and
  the contact flags through tau_J), and what its servos read;
* its compensation of the friction in its drives: Gaz et al.'s law (sim/friction.py)
  times ``friction.compensation``, on its measured velocity, added to every torque it
  commands and in the model its estimate runs on (libfranka docs, "Under the hood":
  tau_c = tau_d + tau_f + tau_g), and measured by its torque sensors.

Its model stays the nominal one (the physics' shared model): the drives carry the model's
weight, not the arm's, and the estimate reads the difference. Nothing here runs for the
ideal robot: the controller builds it at the first draw that is not ideal.
"""

from __future__ import annotations

import numpy as np

from ...reality import DrawBatch, stream
from ...sim.arm import ArmPhysics
from ...sim.friction import JointFriction
from ..state import StateWriter
from .sensors import SensorNoise

__all__ = ["RobotReality", "SensorNoise"]


class RobotReality:
    """The sensors and the friction compensation of n robots whose arms are their draws'
    (the module docstring).

    Args:
        physics: the arms (their truth is enabled here).
        writer: the state writer, whose float64 fields get the measurements.
        scene: the world has a scene the draws change (every robot its own model).
    """

    def __init__(self, physics: ArmPhysics, writer: StateWriter, scene: bool) -> None:
        self.physics = physics
        self.writer = writer
        self.truth = physics.enable_truth(scene)
        n = physics.n
        self.sensors = SensorNoise(n)
        #: the robot's compensation of the friction in its drives
        self.friction = JointFriction(n)
        self._compensation = self.friction.planned(writer.dq)  # at the measured velocity
        self._extra = np.zeros((n, 7))
        # The servos read the robot's measurements (the state's float64 fields).
        physics.sense_with(writer.q, writer.dq)

    def apply(self, robots, draws: DrawBatch) -> None:
        """A new episode of ``robots`` (rows of ``draws``): their arms and worlds, their
        sensors' streams and their friction compensation."""
        robots = np.atleast_1d(np.asarray(robots, dtype=np.intp))
        self.truth.apply(robots, draws)
        rngs = [stream(d.seed, "sensors") for d in draws.draws]
        self.sensors.set(
            robots,
            rngs,
            draws["sensors.q_noise"],
            draws["sensors.dq_noise"],
            draws["sensors.tau_J_noise"],
            draws["sensors.tau_J_offset"],
        )
        self.friction.set_scale(robots, draws["friction.compensation"])

    def model_terms(self, load: np.ndarray | None) -> np.ndarray:
        """(n, 7) what the robot adds to every torque it commands besides its model's
        gravity (which MuJoCo's actuators carry): its friction compensation on its measured
        velocity, plus a configured load's weight (``load``, or None). The same terms are
        in the model its estimate runs on."""
        extra = self._compensation.torque()
        if load is not None:
            return np.add(extra, load, out=self._extra)
        return extra

    def write_measured(self, advance: bool) -> None:
        """The state's measured fields from the physics through the sensors (``advance``:
        a new cycle's samples; False: the samples of this cycle again)."""
        noise = self.sensors.next() if advance else self.sensors.current()
        self.writer.write_measured(self.physics, noise)
