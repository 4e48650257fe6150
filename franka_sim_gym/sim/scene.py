"""The world around the arms: the table every FR3 stands on, and scene fragments.

The table is the plane z = 0 of the world, which is every arm's base plane (bases are
not raised or rotated): the surface the robot is bolted to, unbounded, so it spans the
whole workspace. Its contact is rigid like a table's (``TABLE_SOLREF`` /
``TABLE_SOLIMP``): under 1 mm of penetration at 50 N and stable at the 1 ms step
(tests/sim/test_scene.py). It carries priority 1, so a contact with an arm, hand or
object geom takes the table's parameters, not MuJoCo's soft defaults. link0 is
welded to the world like the table, and MuJoCo never collides two static geoms: the
base cannot touch it.

A scene fragment is an MJCF file whose ``<worldbody>`` holds bodies positioned in an
arm's base frame (objects with a ``<freejoint>``, fixtures without, or as mocap bodies a
task places per episode). The world builder attaches it at the arm's base, with the
arm's name prefix (``arm0/block``); every robot steps its own MjData of that one-arm
world (sim/arm.py), so n robots have n sets of objects that never meet. The project
ships the fragments its tasks use (:data:`SCENES`); any other file can be given by path.
"""

from __future__ import annotations

from pathlib import Path

import mujoco

SCENE_DIR: Path = Path(__file__).resolve().parent / "models" / "scenes"

#: The fragments shipped with the package, by name (``scene="block"``).
SCENES: dict[str, Path] = {
    "block": SCENE_DIR / "block.xml",
    "peg_in_hole": SCENE_DIR / "peg_in_hole.xml",
}

#: Name of the table geom in the compiled world.
TABLE = "table"
#: The contact's time constant (10 ms, critically damped) sets how an impact builds up:
#: the arm meeting the table at 5 cm/s peaks at ~120 N over a few cycles, not at ~600 N
#: in one as with MuJoCo's stiffest safe value (2 timesteps), which bounces the arm off.
TABLE_SOLREF = (0.01, 1.0)
#: ... and the impedance near 1 makes it rigid once pressed: an arm held pressing at
#: ~25 N sinks 0.02 mm, at ~80 N 0.1 mm (MuJoCo's defaults, solimp 0.9-0.95 and solref
#: 0.02, sink it 0.15 mm at 25 N and 0.5 mm at 50 N; tests/sim/test_scene.py).
TABLE_SOLIMP = (0.95, 0.99, 0.001, 0.5, 2.0)


def add_table(spec: mujoco.MjSpec) -> None:
    """The table: the world's z = 0 plane, rigid, winning its contacts' parameters."""
    spec.worldbody.add_geom(
        name=TABLE,
        type=mujoco.mjtGeom.mjGEOM_PLANE,
        size=[0, 0, 0.05],
        rgba=[0.55, 0.5, 0.45, 1],
        solref=list(TABLE_SOLREF),
        solimp=list(TABLE_SOLIMP),
        priority=1,
    )


def scene_path(scene: str | Path) -> Path:
    """The MJCF file of ``scene``: a shipped fragment's name (:data:`SCENES`) or a path.

    Raises:
        ValueError: ``scene`` is neither a shipped name nor an existing file.
    """
    if isinstance(scene, str) and scene in SCENES:
        return SCENES[scene]
    path = Path(scene)
    if not path.is_file():
        names = ", ".join(sorted(SCENES))
        raise ValueError(f"scene {str(scene)!r} is not a shipped scene ({names}) nor a file")
    return path


def load_scene(scene: str | Path) -> mujoco.MjSpec:
    """Parse a scene fragment; a file MuJoCo cannot read is a ValueError naming it."""
    path = scene_path(scene)
    try:
        return mujoco.MjSpec.from_file(str(path))
    except ValueError as exc:  # MuJoCo's parse errors
        raise ValueError(f"scene {str(path)!r}: {exc}") from exc


def body_names(fragment: mujoco.MjSpec) -> list[str]:
    """The names of a fragment's bodies (without the world body), in file order."""
    return [body.name for body in fragment.bodies if body.name and body.name != "world"]


def free_joint_names(fragment: mujoco.MjSpec) -> list[str]:
    """The names of a fragment's free joints: the objects a task may place."""
    return [j.name for j in fragment.joints if j.type == mujoco.mjtJoint.mjJNT_FREE and j.name]
