"""Several fitted policies acting as one: the mean of their actions.

Behaviour cloning fitted to the same 50 demonstrations from different seeds gives actors
that agree where the demonstrations are and err differently away from them; the mean of
their actions averages that disagreement out, not what the demonstrations do not show
(measured in docs/demonstrations.md "PickAndPlace: a solver a clone can follow, and five
clones": PickAndPlace at issue 35's bar on every seed with five, 0.93-0.97 with one;
Push 0.85-0.96 with five, 0.77-0.88 with one). ``examples/train_bc.py --ensemble K``
fits K actors and saves them side by side; ``examples/evaluate.py`` and
``examples/where_it_fails.py`` load them back as one :class:`Ensemble`.

``combine="upward"`` (Cartesian-velocity actions, whose third entry is the TCP's vertical
velocity: docs/env.md, "Actions") takes the vertical velocity of the member that moves
the hand most upward, the mean elsewhere: where the members disagree on coming down,
the most cautious one decides. On Push it took most of the contact reflexes out of five
clones (docs/demonstrations.md, "The members' most upward action").
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

#: Member k > 0 is seeded ``seed + MEMBER_SEED_STRIDE * k``: member 0 is the single
#: actor of the same seed (``--ensemble 1`` is behaviour cloning as before), and the
#: members of runs with seeds 0, 1, 2, ... stay apart.
MEMBER_SEED_STRIDE = 10_000
#: How an ensemble's members' actions make its action.
COMBINE = ("mean", "upward")
#: The vertical TCP velocity's entry of a Cartesian-velocity action (docs/env.md).
VERTICAL = 2


def member_seed(seed: int, k: int) -> int:
    """The seed member ``k`` of an ensemble of run seed ``seed`` is fitted with."""
    if k < 0:
        raise ValueError(f"member index {k} is negative")
    return seed + MEMBER_SEED_STRIDE * k


def member_file(k: int) -> str:
    """Member ``k``'s file name: ``model.zip`` for the first (what every loader reads),
    ``model_member<k>.zip`` beside it for the others."""
    return "model.zip" if k == 0 else f"model_member{k}.zip"


class Ensemble:
    """SB3 models (or anything with SB3's ``predict``) acting as one policy.

    ``predict`` returns the mean of the members' actions for the same observation (one
    or a batch), in the members' dtype; every member sees the same ``deterministic``.
    With ``combine="upward"`` the entry ``VERTICAL`` (a Cartesian-velocity action's
    vertical TCP velocity) is the members' largest instead. Either stays inside a Box
    the members' actions are in.
    """

    def __init__(self, members: Sequence[Any], combine: str = "mean") -> None:
        if len(members) == 0:
            raise ValueError("an ensemble needs at least one member")
        if combine not in COMBINE:
            raise ValueError(f"unknown combine {combine!r}: expected one of {COMBINE}")
        self.members = list(members)
        self.combine = combine

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, None]:
        """The members' combined action for ``observation``; no recurrent state."""
        actions = [m.predict(observation, deterministic=deterministic)[0] for m in self.members]
        combined = np.mean(actions, axis=0)
        if self.combine == "upward":
            combined[..., VERTICAL] = np.max(actions, axis=0)[..., VERTICAL]
        return combined.astype(actions[0].dtype, copy=False), None


def load_members(
    model_path: str | Path,
    members: Sequence[str],
    load: Callable[[Path], Any],
    combine: str = "mean",
):
    """The policy saved at ``model_path``: its train_config.json's ``members`` (file
    names beside it, ``model_path``'s own first) each loaded by ``load``, as an
    :class:`Ensemble` combining them by ``combine`` (its ``combine``); the one model
    when there are no others, or when ``model_path`` names another member (that member
    alone)."""
    path = Path(model_path)
    folder = path.parent
    # SB3 loads "runs/x/model" as "runs/x/model.zip": the same first member
    if not members or path.with_suffix(".zip").name != members[0]:
        return load(path)
    missing = [name for name in members if not (folder / name).is_file()]
    if missing:
        raise FileNotFoundError(f"ensemble members not found beside {model_path}: {missing}")
    models = [load(folder / name) for name in members]
    return models[0] if len(models) == 1 else Ensemble(models, combine)
