"""franka-sim-gym: the Franka FR3's FCI simulated on MuJoCo, for Gymnasium and libfranka clients."""

__version__ = "0.1.0"
