"""Exceptions a user can act on.

Each class is one failure with a fix. The message speaks the API's words
(``overwrite=True``, ``codec_error``); where the command line says it otherwise
(``--overwrite``, ``--codec-error``) the error also carries that wording in
``cli``. The CLI prints ``exc.cli or str(exc)`` as a single line and exits with
``exc.exit_code``: 2 for usage errors (the command line is wrong), 1 for data
errors (the input or the store is wrong).

Examples
--------
>>> e = UsageError("codec_error must be ≥ 0", cli="--codec-error must be ≥ 0")
>>> str(e), e.cli, e.exit_code
('codec_error must be ≥ 0', '--codec-error must be ≥ 0', 2)
"""

from __future__ import annotations


class GeoterrainError(Exception):
    """Base class: a one-line message that says what is wrong and how to fix it."""

    exit_code = 1

    def __init__(self, message: str = "", *, cli: str | None = None):
        super().__init__(message)
        self.cli = cli


class UsageError(GeoterrainError):
    """The request is wrong (an option, a destination that exists, ...)."""

    exit_code = 2


class InputError(GeoterrainError):
    """The input raster cannot be used (unreadable, wrong shape, no valid data, ...)."""


class StoreError(GeoterrainError):
    """A store is missing, incomplete, of another schema version, or damaged."""


class StoreCorruptError(StoreError):
    """A blob's checksum does not match: the file is damaged."""


class StoreChangedError(StoreError):
    """The store was edited (by another process) while it was being read: what the
    reader holds is stale. ``Terrain.refresh()`` reads it again."""


class WriteError(GeoterrainError):
    """The destination cannot be written (read-only directory, full disk, ...)."""


def exists_error(path) -> UsageError:
    """The destination ``path`` exists and overwriting was not asked for."""
    return UsageError(f"{path} exists; pass overwrite=True or choose another destination",
                      cli=f"{path} exists; pass --overwrite or choose another -o path")
