"""Copying per-robot rows: one helper for the batch-first arrays of the controller."""

from __future__ import annotations

import numpy as np


def put_rows(dst: np.ndarray, src: np.ndarray, rows: np.ndarray, every: bool) -> None:
    """Copy ``src`` into ``dst`` on the robots ``rows`` (n,); ``every``: all of them, so a
    plain copy (no mask: the usual case, every robot in the same situation)."""
    if every:
        dst[...] = src
    else:
        np.copyto(dst, src, where=rows.reshape(-1, *(1,) * (dst.ndim - 1)))
