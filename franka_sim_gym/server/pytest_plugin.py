"""The pytest plugin `pip install franka-sim-gym` registers (entry point ``pytest11``).

Fixtures:

* ``franka_sim``: a `franka-sim-gym serve` on a free loopback address, ready (it
  has answered Connect and streamed a state), stopped after the test. Flags
  come from the ``franka_sim`` marker::

      @pytest.mark.franka_sim("--enforce-motion-limits", "--no-gripper")
      def test_my_controller(franka_sim):
          robot = pylibfranka.Robot(franka_sim.host)
          ...
          assert "motion limit violated" not in franka_sim.log()

* ``franka_sim_factory``: a function ``start(*flags, env=None)`` for tests that
  need several servers or choose the flags as they go; all are stopped after it.

Both yield :class:`~franka_sim_gym.server.testing.SimServer` handles (``host``,
``address``, ``log()``, ``alive()``, ``stop()``).

``pytest --franka-sim-lockstep`` serves every one of them with ``--lockstep`` (motions
faster than real time and reproducible; so does ``FRANKA_SIM_LOCKSTEP=1`` in the
environment, which the servers inherit). docs/socket.md has more.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

import pytest

from .testing import SimServer, start_server


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--franka-sim-lockstep",
        action="store_true",
        default=False,
        help="serve every franka_sim / franka_sim_factory robot with `serve --lockstep`: "
        "motions run as fast as the client answers, reproducibly (docs/socket.md)",
    )


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers", "franka_sim(*flags): `franka-sim-gym serve` flags for the franka_sim fixture"
    )


@pytest.fixture
def franka_sim_factory(request, tmp_path) -> Iterator[Callable[..., SimServer]]:
    """Start servers with ``start(*flags, env=None)``; each is stopped after the test."""
    servers: list[SimServer] = []
    lockstep = bool(request.config.getoption("--franka-sim-lockstep", default=False))

    def start(*flags: str, env: dict[str, str] | None = None) -> SimServer:
        log_path = tmp_path / f"franka-sim-{len(servers)}.log"
        server = start_server(*flags, log_path=log_path, env=env, lockstep=lockstep)
        servers.append(server)
        return server

    yield start
    for server in servers:
        server.stop()


@pytest.fixture
def franka_sim(request, franka_sim_factory) -> SimServer:
    """A ready `franka-sim-gym serve` with the ``franka_sim`` marker's flags."""
    marker = request.node.get_closest_marker("franka_sim")
    flags = tuple(marker.args) if marker is not None else ()
    return franka_sim_factory(*flags)
