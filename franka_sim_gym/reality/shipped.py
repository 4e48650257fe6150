"""The shipped reality profiles: ``ideal``, ``fr3`` and ``randomized`` (docs/reality.md
tells each value's source).

Every figure here is either published (cited) or a choice (said so).
"""

from __future__ import annotations

from types import MappingProxyType

#: Franka's datasheet of the Panda (2018-05, "Sensitivity": joint torque sensors and
#: the force estimate): torque noise 0.005 Nm RMS, repeatability 0.05 Nm, relative
#: accuracy 0.15 Nm, resolution 0.02 Nm; force noise 0.035 N RMS, repeatability 0.15 N.
TORQUE_NOISE = 0.005
TORQUE_REPEATABILITY = 0.05
#: Joint position and velocity noise: not published for the FR3 or the Panda; a choice
#: (docs/reality.md): the velocity's noise through the joint servo's damping (~90 Nm s/rad
#: on joint 1) is what makes a resting arm's tau_J move by a few hundredths of a Nm.
Q_NOISE = 5e-6
DQ_NOISE = 5e-4

#: The nominal imperfect FR3's arm: its links' masses and centres of mass differ from the
#: model its FCI holds (the URDF GetRobotModel serves) by these factors and offsets. A
#: choice: values inside ``randomized``'s ranges whose offsets at rest (1.0-1.3 N over
#: docs/reality.md's poses) sit in the 1-2 N franka_ros #404 reports.
FR3_MASS_SCALE = [1.004, 0.988, 1.04, 1.012, 0.974, 0.988, 0.98]
FR3_COM_OFFSET = [
    [0.0001, 0.0019, 0.0036],
    [0.0041, -0.0029, 0.0014],
    [-0.0035, -0.0033, 0.0014],
    [-0.0002, -0.0029, -0.0006],
    [-0.0045, -0.001, -0.0039],
    [0.001, -0.0014, 0.0019],
    [-0.0017, 0.0029, 0.0034],
]
#: ... and the friction in its drives against Gaz et al.'s identified Panda's (what the
#: robot's compensation assumes): a choice inside ``randomized``'s range.
FR3_FRICTION_SCALE = [0.742, 0.93, 1.293, 1.126, 0.789, 0.93, 1.073]

PROFILES = MappingProxyType(
    {
        # The model is the arm, the sensors are exact, the link is perfect.
        "ideal": {},
        # One nominal imperfect FR3 at the published figures.
        "fr3": {
            "model": {
                "mass_scale": FR3_MASS_SCALE,
                "com_offset": FR3_COM_OFFSET,
            },
            "friction": {"scale": FR3_FRICTION_SCALE, "compensation": 1.0},
            "sensors": {
                "tau_J_noise": TORQUE_NOISE,
                "q_noise": Q_NOISE,
                "dq_noise": DQ_NOISE,
            },
            # franka_ros #322: an FR3 on a good link answers 100 % of its cycles.
            "communication": {"loss": 0.0, "jitter": 0.0},
        },
        # Each episode a robot drawn around ``fr3``.
        "randomized": {
            "base": "fr3",
            "model": {
                # robosuite's DomainRandomizationWrapper: mass and inertia +-2 %;
                # MuJoCo Playground: link mass x U(0.9, 1.1). A choice between them.
                "mass_scale": {"uniform": [0.95, 1.05]},
                "com_offset": {"uniform": [-0.005, 0.005]},
            },
            # MuJoCo Playground: friction loss x U(0.5, 2); a choice narrower than it.
            "friction": {"scale": {"uniform": [0.7, 1.3]}},
            "sensors": {
                "tau_J_offset": {"uniform": [-TORQUE_REPEATABILITY, TORQUE_REPEATABILITY]},
            },
            "scene": {
                # Isaac Lab FORGE: held-part mass +-5 g, friction U(0.25, 1.25); MuJoCo
                # Playground: friction U(0.5, 1). Relative to the scenes' 0.1 kg / 0.5.
                "object_mass_scale": {"uniform": [0.8, 1.2]},
                "object_friction_scale": {"uniform": [0.6, 1.4]},
                "table_height": {"uniform": [-0.005, 0.005]},
                "fixture_offset": {"uniform": [-0.001, 0.001]},
            },
            # libfranka #36: a Panda loses 1-5 % and passes the communication test up to
            # 10 %; franka_ros #322: an FR3 should answer 100 %; libfranka #205: jitter
            # spikes of up to 3 ms with some network cards.
            "communication": {
                "loss": {"uniform": [0.0, 0.005]},
                "jitter": {"uniform": [0.0, 0.01]},
                "jitter_cycles": 3,
            },
        },
    }
)
