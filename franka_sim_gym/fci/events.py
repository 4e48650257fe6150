"""What a cycle or a request tells the way in (server or env) to answer.

The controller never replies to anyone itself: it returns events, and the
socket server turns them into TCP replies after the state that explains them
has been sent (docs/fci-behaviour.md "Enabling the violation": the state carrying a reflex
reaches the wire before the kReflexAborted reply).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum


class EventKind(Enum):
    """The deferred answers the controller produces."""

    #: The running Move ended; ``status`` is its final MoveStatus.
    MOVE_FINISHED = "move_finished"
    #: AutomaticErrorRecovery completed; ``status`` is its AutomaticErrorRecoveryStatus.
    RECOVERY_FINISHED = "recovery_finished"


@dataclass(frozen=True)
class Event:
    """One deferred answer for robot ``robot``."""

    robot: int
    kind: EventKind
    status: int
    #: For MOVE_FINISHED: the ended motion's cycle accounting (docs/fci-behaviour.md "The cycle
    #: contract"), so a server can log what the motion's link was like.
    cycles: int = 0
    lost_cycles: int = 0
    longest_lost_run: int = 0
