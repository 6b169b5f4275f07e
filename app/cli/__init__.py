"""The command line: ``handmocap SUBCOMMAND`` (see :mod:`app.cli.main`).

Linear algebra runs on one thread unless the user sets otherwise: our matrices are small (an SVD of a few
hundred frames by a few dozen coordinates in the gap fills, 3x3 fits in the labeller), where a threaded
BLAS only adds overhead, and on a busy machine (Dask workers, the GUI's worker threads, other programs) its
spinning threads made one such SVD 60 times slower (5 ms on one thread, 320 ms on two, load 11 on 2 cores).
This has to happen before numpy is first imported, so it is here, in the package the entry point loads first.
"""

import os

for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")
