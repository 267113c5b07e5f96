"""Whether this process is a fork() child: GNU OpenMP aborts such a child at its first
parallel launch when its parent ran a parallel region, so the compiled kernels with
``prange`` loops switch to serial twins there (:func:`geoterrain.core.threads.forked`). The
package imports this module first, so the hook is in place before any kernel runs."""

from __future__ import annotations

import os

FORKED = [False]
os.register_at_fork(after_in_child=lambda: FORKED.__setitem__(0, True))
