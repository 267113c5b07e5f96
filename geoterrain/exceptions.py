"""Exceptions a user can act on.

Each class is one failure with a fix. The CLI prints ``str(exc)`` as a single
line and exits with ``exc.exit_code``: 2 for usage errors (the command line is
wrong), 1 for data errors (the input or the store is wrong).
"""

from __future__ import annotations


class GeoterrainError(Exception):
    """Base class: a one-line message that says what is wrong and how to fix it."""

    exit_code = 1


class UsageError(GeoterrainError):
    """The request is wrong (an option, a destination that exists, ...)."""

    exit_code = 2


class InputError(GeoterrainError):
    """The input raster cannot be used (unreadable, wrong shape, no valid data, ...)."""


class StoreError(GeoterrainError):
    """A store is missing, incomplete, of another schema version, or damaged."""


class StoreCorruptError(StoreError):
    """A blob's checksum does not match: the file is damaged."""


class WriteError(GeoterrainError):
    """The destination cannot be written (read-only directory, full disk, ...)."""
