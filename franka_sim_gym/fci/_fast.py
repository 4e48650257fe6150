"""Small helpers for the 1 kHz hot path."""

from __future__ import annotations

import numpy as np

try:  # numpy's C implementation, without the Python-level dispatch wrapper (~0.5 us a call)
    from numpy._core.multiarray import count_nonzero
except ImportError:  # pragma: no cover - other numpy layouts
    count_nonzero = np.count_nonzero

try:  # np.einsum's C core, without its Python wrapper (~0.6 us a call): the same arithmetic
    # (np.einsum without ``optimize`` hands its operands to it unchanged); ``out`` must
    # be an array when given
    from numpy._core.multiarray import c_einsum as einsum
except ImportError:  # pragma: no cover - other numpy layouts
    einsum = np.einsum


def put_rows(dst: np.ndarray, src: np.ndarray, rows: np.ndarray, every: bool) -> None:
    """Copy ``src`` into ``dst`` on the robots ``rows`` (n,); ``every``: all of them, so a
    plain copy (no mask: the usual case, every robot in the same situation)."""
    if every:
        dst[...] = src
    else:
        np.copyto(dst, src, where=rows.reshape(-1, *(1,) * (dst.ndim - 1)))


__all__ = ["count_nonzero", "einsum", "put_rows"]
