"""ThreadTuner (envs/sb3_threads.py): torch's thread count for the gradient steps, picked
by timing them, without changing a bit of the training."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

pytest.importorskip("stable_baselines3")
import torch as th  # noqa: E402

from franka_sim_gym.envs.sb3_sac import LeanSAC  # noqa: E402
from franka_sim_gym.envs.sb3_threads import ThreadTuner  # noqa: E402
from tests.training.test_sb3_sac import assert_same_bits, trained  # noqa: E402

#: examples/train_sb3.py's network and batch: the sizes whose kernels must not care.
DEFAULT_SIZES = dict(
    batch_size=256,
    policy_kwargs=dict(net_arch=[128, 128], optimizer_kwargs=dict(foreach=True)),
)


@pytest.fixture(autouse=True)
def _threads_restored():
    before = th.get_num_threads()
    yield
    th.set_num_threads(before)


class Ticks:
    """A clock that advances one second a call: every phase takes as long, so a tuner
    with a negative margin takes each probe."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        self.now += 1.0
        return self.now


def test_the_thread_count_changes_no_bit_of_the_training():
    """The default's sizes, 120 gradient steps: two threads throughout, one throughout, and
    a tuner switching between them at every other phase end with the same parameters and
    Adam moments, bit for bit (what lets the tuner choose by the clock)."""
    two = trained(LeanSAC, callback=ThreadTuner(choices=(2,)), **DEFAULT_SIZES)
    one = trained(LeanSAC, callback=ThreadTuner(choices=(1,)), **DEFAULT_SIZES)
    mixed = ThreadTuner(
        choices=(2, 1), probe_every=1, max_probe_every=1, margin=-0.5, clock=Ticks()
    )
    both = trained(LeanSAC, callback=mixed, **DEFAULT_SIZES)
    assert mixed.phases == 30  # (160 - 40) samples / 4 arms, one phase each
    assert len(mixed.switches) >= 10 and all(mixed.timings.values())
    assert_same_bits(two, one)
    assert_same_bits(two, both)


def _run(tuner: ThreadTuner, seconds_per_phase, phases: int) -> list[int]:
    """Drive the tuner's hooks as SB3's learn does, each gradient phase lasting
    ``seconds_per_phase(phase, threads)``; returns the count of each phase."""
    clock = {"now": 0.0}
    tuner.clock = lambda: clock["now"]
    tuner.model = SimpleNamespace(num_timesteps=100, learning_starts=0, gradient_steps=16)
    tuner._on_training_start()
    used = []
    for phase in range(phases):
        tuner._on_rollout_start()
        tuner._on_rollout_end()
        threads = th.get_num_threads()
        used.append(threads)
        clock["now"] += seconds_per_phase(phase, threads)
    tuner._on_training_end()
    return used


def test_the_tuner_moves_to_one_thread_when_the_machine_gets_busy_and_back():
    """Idle, 2 threads take 3.2 ms a step and 1 thread 4.3 (16 steps a phase); from phase
    100 another process is busy (2 threads 11 ms, 1 thread 3.9), from phase 400 it is
    gone again: the measured figures of docs/env.md."""

    def cost(phase: int, threads: int) -> float:
        busy = 100 <= phase < 400
        per_step = {(False, 2): 3.2, (False, 1): 4.3, (True, 2): 11.0, (True, 1): 3.9}
        return 16 * per_step[(busy, threads)] * 1e-3

    tuner = ThreadTuner(choices=(2, 1))
    used = _run(tuner, cost, 600)
    assert used[0] == 2
    [(to_one, one), (to_two, two)] = tuner.switches
    assert (one, two) == (1, 2)
    assert 100 < to_one <= 100 + 128  # found at the next probe
    assert 400 < to_two <= 400 + 128
    # Probes are rare on a steady machine: the interval doubles up to 128 phases.
    idle = used[:100]
    assert idle.count(1) <= 4
    busy = used[to_one:400]
    assert busy.count(2) <= 1 + (400 - to_one) // 64


def test_a_steady_machine_keeps_the_first_choice_and_probes_ever_less():
    tuner = ThreadTuner(choices=(2, 1), probe_every=8, max_probe_every=128)
    used = _run(tuner, lambda phase, threads: 0.05 if threads == 2 else 0.06, 1000)
    assert tuner.switches == [] and tuner.current == 2
    probes = [k for k, t in enumerate(used) if t == 1]
    gaps = [b - a for a, b in zip(probes, probes[1:], strict=False)]
    assert gaps == sorted(gaps) and gaps[-1] == 129  # 8, 16, ... then every 128 phases
    assert len(probes) <= 12


def test_no_timing_before_learning_starts():
    """SB3 skips the gradient steps until learning_starts: the tuner times nothing."""
    tuner = ThreadTuner(choices=(2, 1))
    tuner.model = SimpleNamespace(num_timesteps=10, learning_starts=300, gradient_steps=16)
    tuner._on_training_start()
    for _ in range(20):
        tuner._on_rollout_start()
        tuner._on_rollout_end()
    tuner._on_training_end()
    assert tuner.phases == 0 and not any(tuner.timings.values())


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (dict(choices=()), "choices must be thread counts >= 1"),
        (dict(choices=(2, 0)), "choices must be thread counts >= 1"),
        (dict(probe_every=0), "need 1 <= probe_every <= max_probe_every"),
        (dict(probe_every=16, max_probe_every=8), "need 1 <= probe_every <= max_probe_every"),
    ],
)
def test_bad_settings_are_named(kwargs, message):
    with pytest.raises(ValueError, match=message):
        ThreadTuner(**kwargs)


def test_an_on_policy_learner_is_timed_too():
    """PPO has no learning_starts: each rollout is followed by its gradient phase."""
    tuner = ThreadTuner(choices=(2, 1))
    tuner.model = SimpleNamespace(num_timesteps=2048, n_steps=2048)  # (PPO's attributes)
    tuner._on_training_start()
    for _ in range(3):
        tuner._on_rollout_start()
        tuner._on_rollout_end()
    tuner._on_training_end()
    assert tuner.phases == 3
