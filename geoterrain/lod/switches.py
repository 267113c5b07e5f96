"""Per-call switches of the LOD selection, light to import (no numba, no VTK).

:func:`occlusion_culling` scopes horizon culling (:mod:`geoterrain.lod.occlusion`):
on by default; a command's ``--no-occlusion`` or ``select(..., occlusion=False)``
switches it off for the selections made inside.
"""

from __future__ import annotations

import contextlib
import contextvars
from collections.abc import Iterator

__all__ = ["occlusion_culling", "occlusion_enabled", "set_occlusion"]

_OCCLUSION: contextvars.ContextVar[bool] = contextvars.ContextVar("geoterrain_occlusion",
                                                                 default=True)


def occlusion_enabled() -> bool:
    """Whether selections in this context cull tiles hidden behind nearer terrain.

    Examples
    --------
    >>> occlusion_enabled()
    True
    """
    return _OCCLUSION.get()


@contextlib.contextmanager
def occlusion_culling(enabled: bool) -> Iterator[None]:
    """Switch horizon culling on or off for the selections made inside the block
    (in this thread: a worker thread takes the setting with it explicitly).

    Examples
    --------
    >>> with occlusion_culling(False):
    ...     occlusion_enabled()
    False
    >>> occlusion_enabled()
    True
    """
    tok = _OCCLUSION.set(bool(enabled))
    try:
        yield
    finally:
        _OCCLUSION.reset(tok)


def set_occlusion(enabled: bool) -> None:
    """Set horizon culling for the rest of this context (a command's whole run)."""
    _OCCLUSION.set(bool(enabled))
