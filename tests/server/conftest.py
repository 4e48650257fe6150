"""Socket-test fixtures: a server factory (the project's pytest plugin) and real clients."""

from __future__ import annotations

import pytest

from tests.socket_helpers import run_client


@pytest.fixture
def serve(franka_sim_factory):
    """``serve(*flags, env=None)``: a ready `franka-sim-gym serve` on its own loopback
    address (the plugin's ``franka_sim_factory``), stopped after the test."""
    return franka_sim_factory


@pytest.fixture
def client():
    """``client(kind, scenario, host)``: a real client scenario in a child process."""
    return run_client
