"""Cycle rate of the FCI controller against bare MuJoCo, in one run.

    python benchmarks/cycle_rate.py [--seconds S] [--breakdown]

Rows: bare mj_step of the world (n = 1 and n = 16 arms), the controller idle
(idle hold), and during a joint-position, a Cartesian-pose and a Cartesian-
velocity motion (one command per arm per cycle, delivered in-process; the
Cartesian ones solved to joint space by the differential IK every cycle).
Each row reports cycles/s, arm-cycles/s and the ratio to bare mj_step of the
same world (the arms on their table, sim/scene.py), counted in this process's CPU time.
"""

from __future__ import annotations

import argparse
import time

import mujoco
import numpy as np
import smoke  # benchmarks/smoke.py: --smoke

from franka_sim_gym.fci.config import ControllerConfig
from franka_sim_gym.fci.controller import FciController
from franka_sim_gym.fci.wire import ROBOT_COMMAND_DTYPE, MoveControllerMode, MoveMotionGeneratorMode
from franka_sim_gym.native import describe
from franka_sim_gym.sim.arm import ArmPhysics

IMPEDANCE = MoveControllerMode.kJointImpedance
CARTESIAN_IMPEDANCE = MoveControllerMode.kCartesianImpedance
JOINT_POSITION = MoveMotionGeneratorMode.kJointPosition
CARTESIAN_POSITION = MoveMotionGeneratorMode.kCartesianPosition
CARTESIAN_VELOCITY = MoveMotionGeneratorMode.kCartesianVelocity


#: The time the rates are counted in: this process's CPU time, so that the other
#: processes of a shared host move the figures little (a wall clock counts their
#: share of the cores too). On an idle core the two agree.
clock = time.process_time


def rate(fn, seconds: float) -> float:
    """Calls of ``fn`` per second over about ``seconds`` (after a short warm-up)."""
    for _ in range(50):
        fn()
    calls, start = 0, clock()
    while True:
        for _ in range(100):
            fn()
        calls += 100
        elapsed = clock() - start
        if elapsed >= seconds:
            return calls / elapsed


def streaming_cycle(ctrl: FciController, field: str, waypoints: np.ndarray):
    """One cycle of an in-process client streaming ``waypoints[k]`` into ``field`` (every
    robot, answering the last published state), then the controller's step."""
    n = ctrl.n
    commands = np.zeros(n, dtype=ROBOT_COMMAND_DTYPE)
    mask = np.ones(n, dtype=bool)
    signal = commands[field]
    message_id = commands["message_id"]
    published = ctrl.states["message_id"]
    period = len(waypoints)
    k = [0]

    def cycle() -> None:
        k[0] += 1
        signal[...] = waypoints[k[0] % period]
        message_id[...] = published
        ctrl.receive(commands, mask)
        ctrl.step()

    return cycle


def bare_step_rate(n: int, seconds: float) -> float:
    """Cycles/s of n one-arm worlds: mj_step on each arm's MjData in a loop."""
    physics = ArmPhysics(n_arms=n)
    model, datas = physics.model, physics.datas

    def step() -> None:
        for data in datas:
            mujoco.mj_step(model, data)

    return rate(step, seconds)


def idle_rate(n: int, seconds: float) -> float:
    ctrl = FciController(ArmPhysics(n_arms=n), ControllerConfig())
    return rate(ctrl.step, seconds)


PERIOD = 4000


def _turn(angle: np.ndarray) -> np.ndarray:
    """(k, 3, 3) rotations about z."""
    c, s = np.cos(angle), np.sin(angle)
    R = np.zeros((len(angle), 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = c, -s, s, c, 1.0
    return R


def motion(n: int, generator, rotate: bool = False, controller=IMPEDANCE):
    """A started controller and its streaming cycle (one command per arm per call).

    The client's waypoints are computed before timing (client work, not the
    controller's): one period of a 4 s cosine, on joint 4 (0.2 rad) or of 5 cm along x
    (as poses, or as their twist), one row per arm per cycle, wrapped (the cosine is
    periodic, so the wrap is smooth). ``rotate`` adds a 0.1 rad turn about z (and
    back) to the Cartesian streams.
    """
    ctrl = FciController(ArmPhysics(n_arms=n), ControllerConfig())
    for i in range(n):
        ctrl.move(i, int(controller), int(generator))
    for _ in range(2):
        ctrl.step()
    t = np.arange(PERIOD) * 1e-3
    bump = 1 - np.cos(2 * np.pi * t / 4.0)  # 0 .. 2 .. 0 over the period
    rate_of_bump = np.sin(2 * np.pi * t / 4.0) * 2 * np.pi / 4.0
    if generator == CARTESIAN_POSITION:
        pose0 = ctrl.states["O_T_EE_d"].astype(np.float64)
        waypoints = np.repeat(pose0[None], PERIOD, axis=0)
        waypoints[:, :, 12] += (0.025 * bump)[:, None]
        if rotate:  # R0 Rz(turn), written column-major (the wire's R^T block)
            R0 = pose0.reshape(n, 4, 4).transpose(0, 2, 1)[:, :3, :3]
            R = np.einsum("nab,tbc->tnac", R0, _turn(0.05 * bump))
            waypoints.reshape(PERIOD, n, 4, 4)[:, :, :3, :3] = R.transpose(0, 1, 3, 2)
        return ctrl, streaming_cycle(ctrl, "O_T_EE_c", waypoints)
    if generator == CARTESIAN_VELOCITY:
        waypoints = np.zeros((PERIOD, n, 6))
        waypoints[:, :, 0] = (0.025 * rate_of_bump)[:, None]
        if rotate:
            waypoints[:, :, 5] = (0.05 * rate_of_bump)[:, None]
        return ctrl, streaming_cycle(ctrl, "O_dP_EE_c", waypoints)
    q0 = ctrl.states["q_d"].astype(np.float64)
    waypoints = np.repeat(q0[None], PERIOD, axis=0)
    waypoints[:, :, 3] += (0.1 * bump)[:, None]
    return ctrl, streaming_cycle(ctrl, "q_c", waypoints)


def motion_rate(n: int, seconds: float) -> float:
    ctrl, cycle = motion(n, JOINT_POSITION)
    cycles = rate(cycle, seconds)
    # The cycle accounting alone (success-rate window, lost runs), every robot counting
    # and answering, as in the motion.
    answered = ctrl.accounting.answered

    def close_cycle() -> None:
        answered[...] = True
        ctrl.accounting.close_cycle()

    accounting = rate(close_cycle, seconds / 4)
    ACCOUNTING_SHARE[n] = cycles / accounting
    # The safety controller on the measured state (errors 3 and 4: fci/limits/_joint.c
    # safety_rule; 2: the self-collision distances), every cycle of a motion.
    safety = rate(ctrl.safety.check, seconds / 4)
    SAFETY[n] = (1e6 / safety, cycles / safety)
    # What the robot senses of contact (fci/contact/sensing.py), every cycle: the model
    # terms, the estimate, the wrench at K and the collision thresholds, one planned C
    # call (fci/contact/_contact.c Sensing).
    in_motion = ctrl.modes.in_motion
    sensing = rate(lambda: ctrl.contact.sense(in_motion, None), seconds / 4)
    SENSING_SHARE[n] = cycles / sensing
    return cycles


#: The pieces of a joint-position cycle, as the controller's public objects call them
#: (controller.py FciController.step); "other" is the controller's own code between them
#: (modes, references, publishing the derived fields) and the client's loop.
PIECES = (
    ("receive", "receive (arrival, cycle input)", lambda c: c),
    ("advance", "joint generators and their limits", lambda c: c.joint),
    ("step", "physics step (servo, mj_step2/mj_step1, rows gathered)", lambda c: c.physics),
    ("write_measured", "state writer: measured fields", lambda c: c.writer),
    ("sense", "contact sensing (model, estimate, wrench, levels)", lambda c: c.contact),
    ("check", "safety controller (errors 2, 3, 4)", lambda c: c.safety),
    ("close_cycle", "cycle accounting", lambda c: c.accounting),
    ("publish", "state writer: publish", lambda c: c.writer),
)


def breakdown(n: int, blocks: int = 500, size: int = 10) -> tuple[dict[str, float], float, float]:
    """Microseconds per joint-position cycle spent in each of :data:`PIECES` and in the
    whole cycle, in the fastest of ``blocks`` blocks of ``size`` cycles (a loaded host
    slows some blocks; the pieces are those of that one block, so they add up), and bare
    mj_step of the same world (its fastest block). Wall clock: CPU time is read by a
    system call, too slow to wrap every piece in."""
    ctrl, cycle = motion(n, JOINT_POSITION)
    clock = time.perf_counter_ns
    spent: dict[str, int] = {}

    def timed(name, method):
        def call(*args, **kwargs):
            start = clock()
            result = method(*args, **kwargs)
            spent[name] = spent.get(name, 0) + clock() - start
            return result

        return call

    for name, _, owner in PIECES:
        obj = owner(ctrl)
        setattr(obj, name, timed(name, getattr(obj, name)))
    physics = ArmPhysics(n_arms=n)
    best, pieces, bare = np.inf, {}, np.inf
    for _ in range(blocks):
        spent.clear()
        start = clock()
        for _ in range(size):
            cycle()
        total = (clock() - start) / size / 1e3
        if total < best:
            best, pieces = total, {name: ns / size / 1e3 for name, ns in spent.items()}
        start = clock()
        for _ in range(size):
            for data in physics.datas:  # every arm's own world, as bare_step_rate
                mujoco.mj_step(physics.model, data)
        bare = min(bare, (clock() - start) / size / 1e3)
    return pieces, best, bare


def cartesian_rate(n: int, seconds: float, generator) -> float:
    """A Cartesian motion: a 4 s cosine of 5 cm along x, as poses or as their twist."""
    return rate(motion(n, generator)[1], seconds)


#: The breakdown's arm counts and issue 38's goal at each (a joint-position motion on the
#: table against bare mj_step of the same worlds).
BREAKDOWN_GOALS = {1: 0.2, 16: 0.7}


def print_breakdown(n: int, goal: float, blocks: int) -> None:
    """Where a joint-position cycle of ``n`` arms goes, and the cycle ``goal`` needs."""
    pieces, total, bare_us = breakdown(n, blocks=blocks)
    print(f"\nwhere a joint-position cycle goes, n={n} (us, wall clock, fastest of {blocks}):")
    print(f"{'bare mj_step of the same world':<50}{bare_us:>8.1f}")
    print(f"{'the whole cycle':<50}{total:>8.1f}{bare_us / total:>8.2f} of bare")
    outer = sum(pieces.values())
    for name, label, _ in PIECES:
        print(f"{label:<50}{pieces[name]:>8.1f}{pieces[name] / total:>8.1%}")
    print(
        f"{'other (controller glue, client loop)':<50}{total - outer:>8.1f}"
        f"{(total - outer) / total:>8.1%}"
    )
    print(f"a ratio of {goal} (issue 38) needs a cycle of {bare_us / goal:.1f} us")


#: per n: the accounting's share of one motion cycle
ACCOUNTING_SHARE: dict[int, float] = {}
#: per n: the safety controller's check, (CPU µs a call, its share of one motion cycle)
SAFETY: dict[int, tuple[float, float]] = {}
#: per n: the contact estimator's and the collision detector's share of one motion cycle
SENSING_SHARE: dict[int, float] = {}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=2.0, help="measuring time per row")
    parser.add_argument(
        "--breakdown", action="store_true", help="also time each piece of a cycle at n = 1, 16"
    )
    args = smoke.parse_args(parser, seconds=0.03, breakdown=True)
    rows = []
    bare = {}
    for n in (1, 16):
        bare[n] = bare_step_rate(n, args.seconds)
        rows.append((f"bare mj_step, n={n}", n, bare[n]))
        rows.append((f"controller idle, n={n}", n, idle_rate(n, args.seconds)))
        rows.append((f"controller joint-position motion, n={n}", n, motion_rate(n, args.seconds)))
        pose = cartesian_rate(n, args.seconds, CARTESIAN_POSITION)
        rows.append((f"controller Cartesian-pose motion, n={n}", n, pose))
        twist = cartesian_rate(n, args.seconds, CARTESIAN_VELOCITY)
        rows.append((f"controller Cartesian-velocity motion, n={n}", n, twist))
        # The same joint motion with the robot's Cartesian impedance servo holding K.
        spring = rate(motion(n, JOINT_POSITION, controller=CARTESIAN_IMPEDANCE)[1], args.seconds)
        rows.append((f"joint-position motion, Cartesian impedance, n={n}", n, spring))
    print(describe())
    print(f"{'row':<50}{'cycles/s':>12}{'arm-cycles/s':>15}{'vs mj_step':>12}")
    for name, n, cycles in rows:
        print(f"{name:<50}{cycles:>12,.0f}{cycles * n:>15,.0f}{cycles / bare[n]:>12.2f}")
    for n, share in ACCOUNTING_SHARE.items():
        print(f"cycle accounting's share of the motion cycle, n={n}: {share:.1%}")
    for n, (us, share) in SAFETY.items():
        print(
            f"the safety controller's check (3, 4, 2), n={n}: {us:.1f} us, "
            f"{share:.1%} of the motion cycle"
        )
    for n, share in SENSING_SHARE.items():
        print(
            f"contact sensing's share (model terms, estimate, wrench, levels), n={n}: {share:.1%}"
        )
    if args.breakdown:
        for n, goal in BREAKDOWN_GOALS.items():
            print_breakdown(n, goal, blocks=20 if args.smoke else 500)
    by_name = {name: cycles for name, _, cycles in rows}
    n1 = by_name["controller joint-position motion, n=1"]
    n16 = by_name["controller joint-position motion, n=16"] * 16
    pose1 = by_name["controller Cartesian-pose motion, n=1"]
    pose16 = by_name["controller Cartesian-pose motion, n=16"] * 16
    print(
        f"summary: mj_step_per_s={bare[1]:.0f} n1_cycles_per_s={n1:.0f} "
        f"n16_arm_cycles_per_s={n16:.0f} cartesian_n1_cycles_per_s={pose1:.0f} "
        f"cartesian_n16_arm_cycles_per_s={pose16:.0f}"
    )


if __name__ == "__main__":
    main()
