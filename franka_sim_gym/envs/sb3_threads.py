"""An SB3 callback that picks torch's thread count for the gradient steps by timing them.

    from franka_sim_gym.envs.sb3_threads import ThreadTuner
    model.learn(total_timesteps=12_000, callback=ThreadTuner())

Why: an off-policy learner's gradient steps are small matrix products (batch 256,
[128, 128] networks), which torch splits across its OpenMP threads. On an idle 2-core
machine two threads take a LeanSAC step in 3.3 ms against 4.0 ms for one. But when any
other process wants a core, the two threads wait for each other at every parallel
region (OpenMP's workers spin, then sleep, while one of them is descheduled): the same
step then takes 13.0 ms with two threads and 4.1 ms with one (benchmarks/sac_step.py,
``--busy``; docs/env.md). Which count is faster depends on what else the machine runs,
minute to minute; so the tuner times it.

How: SB3's off-policy ``learn`` alternates collecting (between ``on_rollout_start`` and
``on_rollout_end``) and its gradient steps (from ``on_rollout_end`` to the next
``on_rollout_start``, or to ``on_training_end``). The tuner times each gradient phase
under the count it set, keeps the median of the last few per count, and runs one phase
under the other count every ``probe_every`` phases: it switches when that probe beats
the current count by ``margin``; each probe that loses doubles the interval to the next
(up to ``max_probe_every``), so a steady machine pays little for the probing.

What it does not change: the results. torch's CPU kernels at these sizes compute every
output element on one thread, whatever the count, so a run's parameters are the same
bits with one thread, two, or any mix (tests/training/test_sb3_threads.py checks it for the
default configuration). Larger batches can make torch split a reduction by thread; then
pass a fixed count instead (``examples/train_sb3.py --threads N``). SB3's TD3 at the
default's sizes gives the same bits at one thread and two as well (measured); PPO was
not checked, and ``examples/train_sb3.py`` uses the tuner for SAC and TD3 only.
"""

from __future__ import annotations

import os
import statistics
import time
from collections import deque
from collections.abc import Callable, Sequence

import torch
from stable_baselines3.common.callbacks import BaseCallback


class ThreadTuner(BaseCallback):
    """Sets ``torch.set_num_threads`` before each gradient phase to whichever of
    ``choices`` has been timed fastest lately.

    Args:
        choices: the thread counts to choose between, the first tried first (default:
            one per core, then 1; a one-core machine has nothing to choose).
        probe_every: gradient phases between two probes of another count, at first.
        max_probe_every: the longest interval, reached by doubling after each lost probe.
        margin: a probe must be this much faster (relative) than the current count's
            median to take over.
        window: how many timings per count the median is taken over.
        clock: the timer (seconds); tests pass a synthetic one.
    """

    def __init__(
        self,
        choices: Sequence[int] | None = None,
        probe_every: int = 8,
        max_probe_every: int = 128,
        margin: float = 0.05,
        window: int = 5,
        clock: Callable[[], float] = time.perf_counter,
    ) -> None:
        super().__init__()
        if choices is None:
            cores = max(1, os.cpu_count() or 1)
            choices = (cores, 1) if cores > 1 else (1,)
        if not choices or any(int(c) < 1 for c in choices):
            raise ValueError(f"choices must be thread counts >= 1, got {choices!r}")
        if probe_every < 1 or max_probe_every < probe_every:
            raise ValueError(
                f"need 1 <= probe_every <= max_probe_every, got {probe_every}, {max_probe_every}"
            )
        self.choices = tuple(dict.fromkeys(int(c) for c in choices))
        self.current = self.choices[0]
        self.probe_every = probe_every
        self.max_probe_every = max_probe_every
        self.margin = margin
        self.clock = clock
        #: the last ``window`` timings (seconds per gradient phase) of each count
        self.timings: dict[int, deque[float]] = {c: deque(maxlen=window) for c in self.choices}
        #: (phase, count) of every switch, for logs and tests
        self.switches: list[tuple[int, int]] = []
        self.phases = 0
        self._interval = probe_every
        self._since_probe = 0
        self._probes = 0
        self._probing: int | None = None
        self._started: float | None = None
        self._running: int | None = None

    def describe(self) -> str:
        """One line: the count in use, the switches, each count's median phase."""
        medians = ", ".join(
            f"{c}: {statistics.median(t) * 1e3:.0f} ms" for c, t in self.timings.items() if t
        )
        moves = " ".join(f"{count}@{phase}" for phase, count in self.switches) or "none"
        return (
            f"{self.current} at the end, {self.phases} gradient phases, switches {moves} "
            f"(latest medians per phase: {medians})"
        )

    # -- SB3's hooks --------------------------------------------------------------------------

    def _on_training_start(self) -> None:
        torch.set_num_threads(self.current)

    def _on_rollout_end(self) -> None:
        model = self.model
        starts = getattr(model, "learning_starts", 0)  # (on-policy learners have none)
        if model.num_timesteps <= starts or getattr(model, "gradient_steps", 1) == 0:
            return  # no gradient phase follows (SB3's learn skips train())
        count = self._next_count()
        torch.set_num_threads(count)
        self._running = count
        self._started = self.clock()

    def _on_rollout_start(self) -> None:
        self._finish_phase()

    def _on_training_end(self) -> None:
        self._finish_phase()

    def _on_step(self) -> bool:
        return True

    # -- the choice ---------------------------------------------------------------------------

    def _next_count(self) -> int:
        """The count for the coming phase: the current one, or a probe of another."""
        others = [c for c in self.choices if c != self.current]
        if others and self._since_probe >= self._interval:
            # (with more than two choices, the others in turn)
            self._probing = others[self._probes % len(others)]
            self._probes += 1
            self._since_probe = 0
            return self._probing
        self._since_probe += 1
        return self.current

    def _finish_phase(self) -> None:
        if self._started is None:
            return
        elapsed = self.clock() - self._started
        count, probe = self._running, self._probing
        self._started = self._running = self._probing = None
        self.phases += 1
        self.timings[count].append(elapsed)
        if probe is None:
            return
        current = statistics.median(self.timings[self.current])
        if elapsed < current * (1.0 - self.margin):
            self.current = probe
            self.switches.append((self.phases, probe))
            self._interval = self.probe_every
            # Its older timings are from another minute of the machine: start afresh.
            self.timings[probe].clear()
            self.timings[probe].append(elapsed)
        else:
            self._interval = min(2 * self._interval, self.max_probe_every)
        torch.set_num_threads(self.current)
