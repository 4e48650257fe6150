"""`franka-sim-gym serve`: the simulated FR3 for libfranka clients (TCP 1337 + UDP),
with the Franka Hand beside it (TCP 1338 + UDP) unless --no-gripper.

Flags and environment variables are those of docs/fci-behaviour.md; a flag wins over its
FRANKA_SIM_* variable.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
from pathlib import Path

from ..fci.config import ControllerConfig, env_flag, env_float
from ..fci.wire.protocol import COMMAND_PORT
from ..reality import RealityDraw, draw, load_profile
from ..sim.arm import ArmPhysics
from ..sim.finger_drive import FingerDrive
from ..sim.gripper import FrankaHand, HandModel
from ..sim.physics_hand import PhysicsHand
from .check import wait_until_ready
from .gripper_server import GRIPPER_PORT, GripperServer
from .lockstep import DEFAULT_TIMEOUT_S
from .robot_server import RobotServer, ServerOptions
from .run_client import run_client


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="franka-sim-gym",
        description="A simulated Franka FR3 behind FCI: Gymnasium env and libfranka server.",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    serve = sub.add_parser(
        "serve",
        help="serve the simulated robot to libfranka clients (pylibfranka, franky, ...)",
        epilog=SERVE_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_serve_arguments(serve)
    check = sub.add_parser(
        "check",
        help="wait until a server answers Connect and streams a state (exit 0), "
        "or time out (exit 1)",
    )
    check.add_argument("host", help="the server's address (as given to serve --host)")
    check.add_argument(
        "--timeout", type=float, default=30.0, metavar="S", help="give up after S s (default 30)"
    )
    check.add_argument("--port", type=int, default=COMMAND_PORT, help="TCP port (default 1337)")
    run = sub.add_parser(
        "run-client",
        help="run an unchanged libfranka program (RealtimeConfig kEnforce) where "
        "/sys/kernel/realtime reads 1 (a private mount namespace; see run_client.py)",
    )
    run.add_argument("client", nargs=argparse.REMAINDER, help="-- CMD [ARG ...]")
    return parser


#: What `serve --help` says about CI (docs/socket.md has the details).
SERVE_EPILOG = """\
in CI:
  franka-sim-gym serve --host 127.0.0.2 &     # start it in the background
  franka-sim-gym check 127.0.0.2 --timeout 60 # exit 0 once Connect is answered
                                              # and a state arrives, 1 on timeout
in pytest (installed with the package):
  def test_my_controller(franka_sim):         # a ready server on a free loopback
      robot = pylibfranka.Robot(franka_sim.host)  # address, stopped after the test
  @pytest.mark.franka_sim("--enforce-motion-limits") chooses its flags;
  franka_sim.log() is its log.
faster than real time, reproducible (the clock waits for the client in motions):
  franka-sim-gym serve --lockstep --enforce-comm-constraints
  pytest --franka-sim-lockstep                # every franka_sim server in lockstep
"""


def add_serve_arguments(serve: argparse.ArgumentParser) -> None:
    serve.add_argument(
        "--host",
        default="127.0.0.1",
        help="address to bind (default 127.0.0.1; libfranka always uses port 1337, so give "
        "several servers their own loopback addresses, e.g. 127.0.0.2)",
    )
    serve.add_argument("--port", type=int, default=COMMAND_PORT, help="TCP port (default 1337)")
    serve.add_argument(
        "--enforce-motion-limits",
        action="store_true",
        default=None,
        help="abort a motion on a motion-limit violation (env FRANKA_SIM_ENFORCE_MOTION_LIMITS)",
    )
    serve.add_argument(
        "--enforce-comm-constraints",
        action="store_true",
        default=None,
        help="abort a motion after 20 consecutive lost cycles "
        "(env FRANKA_SIM_ENFORCE_COMM_CONSTRAINTS)",
    )
    serve.add_argument(
        "--lockstep",
        action="store_true",
        default=None,
        help="during a motion, run each cycle as soon as the client's command for the last "
        "state arrived instead of every 1 ms of wall time; outside motions the stream stays "
        "at 1 kHz (env FRANKA_SIM_LOCKSTEP; docs/socket.md)",
    )
    serve.add_argument(
        "--lockstep-timeout",
        type=float,
        default=None,
        metavar="MS",
        help="with --lockstep, how long a state waits for its answer before the cycle counts "
        f"as lost, below 1000 (default {DEFAULT_TIMEOUT_S * 1e3:g} ms; env "
        "FRANKA_SIM_LOCKSTEP_TIMEOUT)",
    )
    serve.add_argument(
        "--joint-discontinuity-scale",
        type=float,
        default=None,
        help="scale the joint-side limits of Cartesian commands "
        "(env FRANKA_SIM_JOINT_DISCONTINUITY_SCALE)",
    )
    serve.add_argument(
        "--robot",
        choices=("fr3", "fer"),
        default="fr3",
        help="limit tables: fr3 (FCI v10, default) or fer (the Panda's v5 tables)",
    )
    serve.add_argument("--urdf", type=Path, default=None, help="URDF served by GetRobotModel")
    serve.add_argument(
        "--scene",
        default=None,
        metavar="SCENE",
        help="objects on the robot's table: a shipped scene (block, peg_in_hole) or an MJCF "
        "file whose bodies are placed in the base frame (default: the bare table)",
    )
    serve.add_argument(
        "--payload",
        default=None,
        metavar="MASS,X,Y,Z",
        help="a mass [kg] fixed to the flange, centre of mass x,y,z [m] in the flange frame, "
        "that the robot is not told of: configure it with SetLoad (default: none)",
    )
    serve.add_argument(
        "--reality",
        default=None,
        metavar="PROFILE",
        help="how the robot differs from its model and from ideal sensors: ideal (default), "
        "fr3, randomized, or a JSON file (env FRANKA_SIM_REALITY; docs/reality.md)",
    )
    serve.add_argument(
        "--reality-seed",
        type=int,
        default=None,
        metavar="N",
        help="the seed of the profile's draw and of the sensors' noise (default 0; env "
        "FRANKA_SIM_REALITY_SEED)",
    )
    serve.add_argument("-v", "--vis", action="store_true", help="open the MuJoCo viewer")
    serve.add_argument("--log-level", default="INFO", help="logging level (default INFO)")
    hand = serve.add_mutually_exclusive_group()
    hand.add_argument(
        "--no-gripper", action="store_true", help="do not serve the Franka Hand on port 1338"
    )
    hand.add_argument(
        "--gripper-physics",
        action="store_true",
        help="mount the Franka Hand on the arm's flange in MuJoCo (reported as Desk's "
        "end-effector configuration: load, F_T_NE at its TCP) and drive its fingers on a "
        "force-limited PD servo (default: the kinematic hand, not mounted)",
    )
    serve.add_argument(
        "--gripper-object-width",
        type=float,
        default=None,
        metavar="W",
        help="a rigid virtual object W m wide between the fingers "
        "(env FRANKA_SIM_GRIPPER_OBJECT_WIDTH; default: nothing graspable)",
    )


def serve(args: argparse.Namespace) -> int:
    logging.basicConfig(
        level=getattr(logging, str(args.log_level).upper(), logging.INFO),
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
    )
    try:
        config = ControllerConfig.from_environment(
            robot=args.robot,
            enforce_motion_limits=args.enforce_motion_limits,
            enforce_comm_constraints=args.enforce_comm_constraints,
            joint_discontinuity_scale=args.joint_discontinuity_scale,
        )
    except ValueError as exc:
        print(f"franka-sim-gym serve: {exc}", file=sys.stderr)
        return 2
    if args.urdf is not None and not args.urdf.is_file():
        print(f"franka-sim-gym serve: --urdf {args.urdf}: no such file", file=sys.stderr)
        return 2
    try:
        lockstep, timeout = lockstep_options(args.lockstep, args.lockstep_timeout)
        reality = reality_draw(args.reality, args.reality_seed)
    except ValueError as exc:
        print(f"franka-sim-gym serve: {exc}", file=sys.stderr)
        return 2
    options = ServerOptions(
        host=args.host,
        port=args.port,
        urdf=args.urdf,
        lockstep=lockstep,
        lockstep_timeout=timeout,
        reality=reality,
    )
    try:
        server, gripper = _servers(args, config, options)
    except ValueError as exc:
        print(f"franka-sim-gym serve: {exc}", file=sys.stderr)
        return 2
    if args.vis:
        server.open_viewer()
    if gripper is not None:
        try:
            gripper.start()
        except OSError as exc:
            print(
                f"franka-sim-gym serve: cannot serve the gripper on {args.host}:{GRIPPER_PORT}: "
                f"{exc} (--no-gripper serves the arm alone)",
                file=sys.stderr,
            )
            return 1
    try:
        server.serve_forever()
    except OSError as exc:
        print(
            f"franka-sim-gym serve: cannot serve on {args.host}:{args.port}: {exc}", file=sys.stderr
        )
        return 1
    finally:
        if gripper is not None:
            gripper.stop()
    return 0


#: libfranka's blocking state receive gives up after 1 s (docs/libfranka-client.md §10):
#: a client waiting for the state after the motion's first (which it does not answer)
#: must get it sooner, so a lockstep wait stays below that [ms].
MAX_LOCKSTEP_TIMEOUT_MS = 1000.0


def lockstep_options(flag: bool | None, timeout_ms: float | None) -> tuple[bool, float]:
    """(lockstep, its timeout [s]) from --lockstep / --lockstep-timeout MS, else from
    FRANKA_SIM_LOCKSTEP / FRANKA_SIM_LOCKSTEP_TIMEOUT (the flag wins); ValueError when
    the timeout is not a positive number of milliseconds."""
    lockstep = flag if flag is not None else bool(env_flag("FRANKA_SIM_LOCKSTEP"))
    if timeout_ms is None:
        timeout_ms = env_float("FRANKA_SIM_LOCKSTEP_TIMEOUT")
    if timeout_ms is None:
        return lockstep, DEFAULT_TIMEOUT_S
    if not (timeout_ms > 0 and timeout_ms < MAX_LOCKSTEP_TIMEOUT_MS):
        raise ValueError(
            f"--lockstep-timeout {timeout_ms!r}: expected more than 0 and less than "
            f"{MAX_LOCKSTEP_TIMEOUT_MS:g} ms (libfranka gives up on a state after 1 s)"
        )
    return lockstep, timeout_ms / 1e3


def reality_draw(profile: str | None, seed: int | None) -> RealityDraw | None:
    """The served robot's draw from --reality PROFILE / --reality-seed N, else from
    FRANKA_SIM_REALITY / FRANKA_SIM_REALITY_SEED (the flag wins); None for the ideal
    robot. ValueError for a bad profile (named) or a seed that is not a whole number."""
    if profile is None:
        profile = os.environ.get("FRANKA_SIM_REALITY", "").strip() or "ideal"
    if seed is None:
        text = os.environ.get("FRANKA_SIM_REALITY_SEED", "").strip()
        try:
            seed = int(text) if text else 0
        except ValueError:
            raise ValueError(f"FRANKA_SIM_REALITY_SEED={text!r} is not a whole number") from None
    if seed < 0:
        raise ValueError(f"--reality-seed {seed}: expected a whole number >= 0")
    chosen = load_profile(profile)
    return None if chosen.is_ideal else draw(chosen, seed)


def _object_width(args: argparse.Namespace) -> float | None:
    """--gripper-object-width, else FRANKA_SIM_GRIPPER_OBJECT_WIDTH (the flag wins)."""
    width = args.gripper_object_width
    if width is None and os.environ.get("FRANKA_SIM_GRIPPER_OBJECT_WIDTH", "").strip():
        text = os.environ["FRANKA_SIM_GRIPPER_OBJECT_WIDTH"]
        try:
            width = float(text)
        except ValueError:
            raise ValueError(f"FRANKA_SIM_GRIPPER_OBJECT_WIDTH={text!r} is not a number") from None
    return width


def _servers(
    args: argparse.Namespace, config: ControllerConfig, options: ServerOptions
) -> tuple[RobotServer, GripperServer | None]:
    """The arm, and the Franka Hand on port 1338 of the same host unless --no-gripper
    (docs/fci-behaviour.md "Gripper fidelity").

    The kinematic hand is not mounted on the arm. --gripper-physics mounts the
    hand (and the virtual object) in the arm's MuJoCo world, whose tick thread
    then runs the finger drive; the controller then reports the hand's load and
    TCP (F_T_NE) in the RobotState (FciController reads them off the model).
    """
    world = {"scene": args.scene, "payload": _payload(args.payload)}
    if args.no_gripper:
        return RobotServer(config, options, physics=ArmPhysics(n_arms=1, **world)), None
    width = _object_width(args)
    hand: HandModel
    if args.gripper_physics:
        physics = ArmPhysics(n_arms=1, hand=True, object_width=width, **world)
        drive = FingerDrive(physics)
        server = RobotServer(config, options, physics=physics)
        server.add_tick_hook(drive.tick)
        hand = PhysicsHand(drive, object_width=width)
    else:
        hand = FrankaHand(object_width=width)
        server = RobotServer(config, options, physics=ArmPhysics(n_arms=1, **world))
    return server, GripperServer(host=args.host, port=GRIPPER_PORT, hand=hand)


def _payload(text: str | None) -> tuple[float, float, float, float] | None:
    """--payload MASS,X,Y,Z as four numbers (ArmPhysics checks their values)."""
    if text is None:
        return None
    try:
        mass, x, y, z = (float(v) for v in text.split(","))
    except ValueError:
        raise ValueError(f"--payload {text!r}: expected MASS,X,Y,Z (four numbers)") from None
    return mass, x, y, z


def check(args: argparse.Namespace) -> int:
    """`franka-sim-gym check HOST`: 0 once a server is ready, 1 after --timeout."""
    why = wait_until_ready(args.host, args.port, timeout=args.timeout)
    if why is None:
        print(
            f"franka-sim-gym check: {args.host}:{args.port} is ready (Connect answered, "
            "state received)"
        )
        return 0
    print(
        f"franka-sim-gym check: {args.host}:{args.port} not ready after {args.timeout:g} s: {why}",
        file=sys.stderr,
    )
    return 1


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.command == "serve":
        return serve(args)
    if args.command == "check":
        return check(args)
    if args.command == "run-client":
        command = args.client[1:] if args.client[:1] == ["--"] else args.client
        return run_client(command)
    return 2  # pragma: no cover


if __name__ == "__main__":
    sys.exit(main())
