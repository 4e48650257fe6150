"""The robot server's command ids and reply status enums (docs/wire-protocol.md §3).

``protocol`` re-exports them; the controller answers requests with them.
"""

from __future__ import annotations

from enum import IntEnum


class Command(IntEnum):
    """§3: command ids of robot server v10."""

    kConnect = 0
    kMove = 1
    kStopMove = 2
    kSetCollisionBehavior = 3
    kSetJointImpedance = 4
    kSetCartesianImpedance = 5
    kSetGuidingMode = 6
    kSetEEToK = 7
    kSetNEToEE = 8
    kSetLoad = 9
    kAutomaticErrorRecovery = 10
    kGetRobotModel = 11


# §3.1 status enums (all u8; 0 = success everywhere).
class ConnectStatus(IntEnum):
    """§3.1 C: Connect reply status."""

    kSuccess = 0
    kIncompatibleLibraryVersion = 1


class MoveStatus(IntEnum):
    """§3.1 D: Move reply status (sent twice: kMotionStarted, then the final status)."""

    kSuccess = 0
    kMotionStarted = 1
    kPreempted = 2
    kPreemptedDueToActivatedSafetyFunctions = 3
    kCommandRejectedDueToActivatedSafetyFunctions = 4
    kCommandNotPossibleRejected = 5
    kStartAtSingularPoseRejected = 6
    kInvalidArgumentRejected = 7
    kReflexAborted = 8
    kEmergencyAborted = 9
    kInputErrorAborted = 10
    kAborted = 11


class StopMoveStatus(IntEnum):
    """§3.1 E: StopMove reply status."""

    kSuccess = 0
    kCommandNotPossibleRejected = 1
    kCommandRejectedDueToActivatedSafetyFunctions = 2
    kEmergencyAborted = 3
    kReflexAborted = 4
    kAborted = 5


class SetterStatus(IntEnum):
    """§3.1 B: status of the setters (ids 3-9)."""

    kSuccess = 0
    kCommandNotPossibleRejected = 1
    kInvalidArgumentRejected = 2
    kCommandRejectedDueToActivatedSafetyFunctions = 3


class GetterStatus(IntEnum):
    """§3.1 A: the Basic status enum, used by GetRobotModel."""

    kSuccess = 0
    kCommandNotPossibleRejected = 1
    kCommandRejectedDueToActivatedSafetyFunctions = 2


class AutomaticErrorRecoveryStatus(IntEnum):
    """§3.1 F: AutomaticErrorRecovery reply status."""

    kSuccess = 0
    kCommandNotPossibleRejected = 1
    kCommandRejectedDueToActivatedSafetyFunctions = 2
    kManualErrorRecoveryRequiredRejected = 3
    kReflexAborted = 4
    kEmergencyAborted = 5
    kAborted = 6
