"""How many threads the compiled row-parallel kernels use (:mod:`admmkit.linalg.vcycle`, :mod:`admmkit.linalg.vcycle_blocks`).

The row-parallel kernels sum every row in its stored order on one thread,
so the values do not depend on the count; only the time does.
"""
from __future__ import annotations

import os

from numba import get_num_threads, set_num_threads

#: environment variable naming the threads of the row-parallel kernels (default 1)
THREADS_VARIABLE = "ADMMKIT_KERNEL_THREADS"


def kernel_threads() -> int:
    """Threads for the row-parallel kernels: ``$ADMMKIT_KERNEL_THREADS`` (default 1), at most numba's pool.

    One by default: on this project's shared 2-core machine, with the other core busy, a product of
    1e6 rows took 0.0093 s on one thread and 0.012-0.016 s on two (the second thread waits for a core);
    on an idle core two took 0.0126 s against scipy's 0.0183 s.  The values do not depend on it.
    Sets numba's count for the calling thread and returns it.
    """
    try:
        wanted = int(os.environ.get(THREADS_VARIABLE, "1"))
    except ValueError:
        wanted = 1
    from numba import config
    threads = max(1, min(wanted, config.NUMBA_NUM_THREADS))
    if get_num_threads() != threads:
        set_num_threads(threads)
    return threads
