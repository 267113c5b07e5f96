"""Whether this process is a fork() child: GNU OpenMP aborts such a child at its first
parallel launch when its parent ran a parallel region, so the compiled kernels with
``prange`` loops switch to serial twins there (:func:`geoterrain.core.threads.forked`). The
package imports this module first, so the hook is in place before any kernel runs.

It also sets GNU OpenMP's wait policy, which the library reads once, when numba first
loads it: ``PASSIVE`` (unless the environment sets ``OMP_WAIT_POLICY``), so a thread that
reaches a parallel region's end sleeps instead of spinning. On a shared machine the spin
took the core from the thread still working (and from other jobs): a 4097² preprocess
at load 6.5–7 on the 2-core VM, three alternating pairs, took 18.2–21.5 s and 7.0–8.4 s
of CPU passive against 22.1–22.9 s and 8.5–9.1 s spinning (docs/lab/preprocess.md); a
sleeping thread's wake-up costs tens of microseconds a region on an idle machine."""

from __future__ import annotations

import os

FORKED = [False]
os.register_at_fork(after_in_child=lambda: FORKED.__setitem__(0, True))
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
