"""Options shared between commands, and the progress bar."""

from __future__ import annotations

import sys

import click


def parse_triple(ctx, param, value):
    """Parse ``X,Y,Z`` into a tuple of three floats."""
    if value is None:
        return None
    try:
        parts = tuple(float(v) for v in value.split(","))
    except ValueError:
        raise click.BadParameter(f"expected X,Y,Z numbers, got {value!r}") from None
    if len(parts) != 3:
        raise click.BadParameter(f"expected three numbers X,Y,Z, got {value!r}")
    return parts


def parse_size(ctx, param, value):
    """Parse ``WxH`` into (width, height)."""
    if value is None:
        return None
    try:
        w, h = (int(v) for v in value.lower().split("x"))
    except ValueError:
        raise click.BadParameter(f"expected WIDTHxHEIGHT such as 1280x720, got {value!r}") from None
    if w < 16 or h < 16 or w > 16384 or h > 16384:
        raise click.BadParameter(f"size {w}x{h} out of range (16..16384 per side)")
    return w, h


class StageBar:
    """A progress bar over named stages, on stderr; silent with -q."""

    def __init__(self, label: str, quiet: bool):
        self.quiet = quiet
        self.label = label
        self.bar = None

    def __call__(self, stage: str, done: int, total: int) -> None:
        if self.quiet:
            return
        if self.bar is None:
            self.bar = click.progressbar(length=total, label=self.label, file=sys.stderr,
                                         show_eta=False, item_show_func=lambda s: s)
            self.bar.__enter__()
        self.bar.update(done - self.bar.pos, stage)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.__exit__(None, None, None)
            self.bar = None
