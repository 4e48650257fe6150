"""Socket-test fixtures: a server factory (the project's pytest plugin) and real clients,
defined once in tests/socket_helpers.py."""

from tests.socket_helpers import client, serve  # noqa: F401 (fixtures, by name)
