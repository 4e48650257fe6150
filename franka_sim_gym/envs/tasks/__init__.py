"""Tasks: what an episode is about (goals, objects, reward, success); the batched core
(envs/core.py) does the rest. The protocol is ``Task`` (tasks/base.py).

A new task is one file here (a ``Task`` subclass) and one line in ``TASKS``;
``envs/__init__.py`` registers its Gymnasium ids from it.
"""

from __future__ import annotations

from .base import Task
from .peg_insertion import PegInsertion
from .pick_and_place import PickAndPlace
from .push import Push
from .reach import Reach

#: Every task by name (the env's ``task`` argument). One line per task.
TASKS: dict[str, type[Task]] = {
    "reach": Reach,
    "push": Push,
    "pick_and_place": PickAndPlace,
    "peg_insertion": PegInsertion,
}


def make_task(task: str | Task, **kwargs) -> Task:
    """A task from its name in ``TASKS`` (with ``kwargs``: its arguments) or an instance."""
    if isinstance(task, Task):
        if kwargs:
            raise ValueError(f"task arguments {sorted(kwargs)} go to the task's constructor")
        return task
    if task not in TASKS:
        raise ValueError(f"unknown task {task!r}: expected one of {tuple(TASKS)} or a Task")
    return TASKS[task](**kwargs)


__all__ = ["TASKS", "PegInsertion", "PickAndPlace", "Push", "Reach", "Task", "make_task"]
