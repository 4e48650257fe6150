"""Gymnasium environments (see the env issue); drives franka_sim_gym.fci in-process."""
