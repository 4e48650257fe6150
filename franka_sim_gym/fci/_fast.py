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

__all__ = ["count_nonzero", "einsum"]
