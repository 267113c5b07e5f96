"""An edit computed over the tiles it reaches only (placeholder)."""

from __future__ import annotations


def unsupported(terrain, row, col, heights, valid) -> str:
    return "the local computation is not built yet"


def local_plan(terrain, row, col, heights, valid):
    return None, "not built"
