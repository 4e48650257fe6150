"""MuJoCo side: the FR3 model files, stepping, the joint servo, gravity compensation."""
