"""One BLAS thread for this program's linear algebra.

The matrices the program multiplies and decomposes are small: at most a few hundred columns (a PCA fill's
window of a two-hand take: 156; Kabsch fits: 3 × 3; IK steps: 26). On those, a second BLAS thread saves
little time and costs CPU time in spinning and hand-over, more so when the other cores are busy: a fill of a
two-hand take took 3.7 times the CPU time with OpenBLAS's two threads on this two-core machine, labelling
1.5 times (identical results). ``HANDMOCAP_BLAS_THREADS`` sets another count. Dask's workers already run
with one thread (its nanny sets the same variables).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager

#: the variables the BLAS libraries read when they load (OpenBLAS, OpenMP builds, MKL)
BLAS_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def blas_threads() -> int:
    """The BLAS threads to use: ``$HANDMOCAP_BLAS_THREADS`` when it is a positive integer, else 1."""
    configured = os.environ.get("HANDMOCAP_BLAS_THREADS", "")
    return int(configured) if configured.isdigit() and int(configured) > 0 else 1


def limit_blas_threads() -> None:
    """For the whole process (the command line and the window): the BLAS libraries loaded already run
    :func:`blas_threads` threads, and those loaded later read it from the environment (a variable the user set
    is kept)."""
    from threadpoolctl import threadpool_limits

    threads = blas_threads()
    for variable in BLAS_VARIABLES:
        os.environ.setdefault(variable, str(threads))
    threadpool_limits(limits=threads, user_api="blas")


@contextmanager
def blas_threads_limited() -> Iterator[None]:
    """Within the block only (a call of the Python API in a user's own process): :func:`blas_threads`
    threads for numpy's and scipy's BLAS libraries, their previous counts restored after."""
    import scipy.linalg  # noqa: F401 - scipy's own BLAS is loaded now, so that the limit reaches it
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=blas_threads(), user_api="blas"):
        yield
