"""The grids δ is computed on: a square of side N = 2**n + 1, or a root grid's extent
(roots of side ``span``), checked and made contiguous, non-finite heights invalid
(:mod:`geoterrain.bounds.delta`'s rules)."""

from __future__ import annotations

import numpy as np

__all__ = ["check_grid", "grid_order"]


def grid_order(N: int) -> int:
    """n for a grid side N = 2**n + 1 (n ≥ 1); ValueError otherwise."""
    n = int(N - 1).bit_length() - 1
    if N < 3 or (1 << n) + 1 != N:
        raise ValueError(f"grid side must be 2**n + 1 with n >= 1, got {N}")
    return n


def check_grid(z: np.ndarray, valid: np.ndarray, span: int | None = None
               ) -> tuple[np.ndarray, np.ndarray, int]:
    """Checked, contiguous ``(z, valid, n)``: non-finite heights become invalid, and
    invalid heights 0 (never read). ``span``: a root grid's root side 2**n, the arrays
    then a whole number of roots each way (see the module's docstring)."""
    z = np.asarray(z, dtype=np.float64)
    valid = np.asarray(valid, dtype=bool)
    if span is None:
        if z.ndim != 2 or z.shape[0] != z.shape[1] or valid.shape != z.shape:
            raise ValueError(f"z and valid must be the same (N, N) shape, got {z.shape}, "
                             f"{valid.shape}")
        n = grid_order(z.shape[0])
    else:
        n = grid_order(span + 1)
        if z.ndim != 2 or valid.shape != z.shape or any((k - 1) % span or k < 3
                                                         for k in z.shape):
            raise ValueError(f"z and valid must be the same (ry·{span} + 1, rx·{span} + 1) "
                             f"shape, got {z.shape}, {valid.shape}")
    if valid.all() and np.isfinite(z).all():
        return np.ascontiguousarray(z), np.ascontiguousarray(valid), n
    valid = valid & np.isfinite(z)
    zf = np.where(valid, z, 0.0)  # invalid heights are never read
    return zf, valid, n
