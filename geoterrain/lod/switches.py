"""Per-call switches of the LOD selection, light to import (no numba, no VTK).

- :func:`occlusion_culling` scopes horizon culling (:mod:`geoterrain.lod.occlusion`):
  on by default; a command's ``--no-occlusion`` or ``select(..., occlusion=False)``
  switches it off for the selections made inside.
- :func:`geomorphing` scopes geomorphing (rtin: :mod:`geoterrain.lod.morph`,
  chunked: :func:`geoterrain.lod.chunks.morph_heights` and geomipmap:
  :mod:`geoterrain.lod.geomipmap_morph`, off by default; cdlod: on by default);
  ``--morph/--no-morph`` or ``select(..., morph=...)`` chooses for every strategy that
  can.
"""

from __future__ import annotations

import contextlib
import contextvars
from collections.abc import Iterator

__all__ = ["geomorphing", "morphing_choice", "morphing_enabled", "occlusion_culling",
           "occlusion_enabled"]

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


_MORPH: contextvars.ContextVar[bool | None] = contextvars.ContextVar("geoterrain_morph",
                                                                    default=None)


def morphing_enabled() -> bool:
    """Whether selections in this context geomorph where it is optional (rtin: off
    unless switched on; see :func:`morphing_choice`).

    Examples
    --------
    >>> morphing_enabled()
    False
    """
    return bool(_MORPH.get())


def morphing_choice() -> bool | None:
    """The explicit choice (True/False), or None: each strategy's own default (rtin
    does not morph, cdlod does).

    Examples
    --------
    >>> morphing_choice() is None
    True
    """
    return _MORPH.get()


@contextlib.contextmanager
def geomorphing(enabled: bool) -> Iterator[None]:
    """Switch geomorphing on or off for the selections made inside the block.

    Examples
    --------
    >>> with geomorphing(True):
    ...     morphing_enabled()
    True
    """
    tok = _MORPH.set(bool(enabled))
    try:
        yield
    finally:
        _MORPH.reset(tok)

