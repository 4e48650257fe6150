"""Addresses in the libmujoco the Python bindings ship, for the C texts that call MuJoCo.

``sim/_ik.c`` calls ``mj_kinematics`` between its passes and ``sim/_stepping.c`` runs a
cycle's ``mj_step2`` / ``mj_step1`` of every arm: both through the functions of the very
library the bindings have loaded (the same code as ``mujoco.mj_kinematics`` and
``mujoco.mj_step2``), looked up here by name. The structs' addresses are the bindings'
``_address`` (tested in MuJoCo's own bindings tests).
"""

from __future__ import annotations

import ctypes
import functools
from pathlib import Path

import mujoco

__all__ = ["function_address", "library"]


@functools.cache
def library() -> ctypes.CDLL | None:
    """The bindings' libmujoco (``libmujoco.so.X`` beside the ``mujoco`` package), or
    None where there is none to load."""
    package = Path(mujoco.__file__).parent
    for path in sorted(package.glob("*mujoco*")):
        if path.suffix not in {".so", ".dylib", ".dll"} and ".so." not in path.name:
            continue
        if path.name.startswith("_"):  # the bindings' own extension modules
            continue
        try:
            lib = ctypes.CDLL(str(path))
            lib.mj_step  # noqa: B018 -- a libmujoco, not some other library of the name
        except (OSError, AttributeError):
            continue
        return lib
    return None


def function_address(name: str) -> int | None:
    """The address of MuJoCo's C function ``name``; None where it cannot be had."""
    lib = library()
    try:
        function = getattr(lib, name) if lib is not None else None
    except AttributeError:
        return None
    return None if function is None else ctypes.cast(function, ctypes.c_void_p).value
