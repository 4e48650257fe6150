"""Speed profiles the socket tests stream (no imports: the client scripts load it too)."""

from __future__ import annotations


def there_and_back(v_max: float, a_max: float, j_max: float, rest: int = 50) -> list[float]:
    """A speed per 1 ms cycle: up to ``v_max`` at ``a_max`` by the jerk budget ``j_max``
    (braking the acceleration in time, as tests/cartesian_helpers.py ramp_x), the same
    down to rest, then ``rest`` cycles at rest."""
    up, v, a = [], 0.0, 0.0
    while v < v_max - 1e-12 or a > 0.0:
        if v + a * a / (2.0 * j_max) >= v_max - 1e-12:
            a = max(a - j_max * 1e-3, 0.0)
        else:
            a = min(a + j_max * 1e-3, a_max)
        v = min(v + a * 1e-3, v_max)
        up.append(v)
    return up + up[::-1] + [0.0] * rest


def positions(speeds: list[float]) -> list[float]:
    """The offsets the speeds integrate to, one per cycle (the first 0)."""
    x = [0.0]
    for v in speeds:
        x.append(x[-1] + v * 1e-3)
    return x
