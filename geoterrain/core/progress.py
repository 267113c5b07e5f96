"""The stages of a long job: their times and the progress callback they report to."""

from __future__ import annotations

import time
from collections.abc import Callable

__all__ = ["Progress", "StageClock"]

# progress(stage name, stages done, stages in all)
Progress = Callable[[str, int, int], None]


class StageClock:
    """Times a job's named stages, each from the end of the one before, and reports
    each to ``progress`` as it ends.

    Examples
    --------
    >>> seen = []
    >>> clock = StageClock(("read", "write"), lambda *a: seen.append(a))
    >>> clock("read"); clock("write")
    >>> seen, sorted(clock.times)
    ([('read', 1, 2), ('write', 2, 2)], ['read', 'write'])
    """

    def __init__(self, stages: tuple[str, ...], progress: Progress | None = None,
                 times: dict | None = None) -> None:
        self.stages = stages
        self.progress = progress
        self.times: dict[str, float] = {} if times is None else times  # the caller's dict
        self.times.clear()
        self._t0 = time.perf_counter()

    def __call__(self, name: str) -> None:
        now = time.perf_counter()
        self.times[name] = round(now - self._t0, 4)
        self._t0 = now
        if self.progress:
            self.progress(name, len(self.times), len(self.stages))
