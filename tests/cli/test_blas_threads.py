"""One BLAS thread (core/blas.py): the command line limits the whole process, the Python API only its own calls;
HANDMOCAP_BLAS_THREADS and a thread count the user set are kept."""

import json
import os
import subprocess
import sys

CHECK = """
import json, os
import numpy
from threadpoolctl import threadpool_info
from handmocap.core.blas import blas_threads_limited, limit_blas_threads

def counts():
    return sorted({pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"})

before = counts()
with blas_threads_limited():
    inside = counts()
after = counts()
limit_blas_threads()
print(json.dumps({"before": before, "inside": inside, "after": after, "process": counts(),
                  "variable": os.environ.get("OPENBLAS_NUM_THREADS")}))
"""


def _run(**variables: str) -> dict:
    environment = {name: value for name, value in os.environ.items()
                   if name not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS",
                                   "HANDMOCAP_BLAS_THREADS")}
    completed = subprocess.run([sys.executable, "-c", CHECK], env=environment | variables, capture_output=True,
                               text=True, timeout=120)
    assert completed.returncode == 0, completed.stderr
    return json.loads(completed.stdout.splitlines()[-1])


def test_one_blas_thread_for_the_process_and_within_an_api_call():
    counts = _run()
    assert counts["inside"] == [1] and counts["process"] == [1] and counts["variable"] == "1"
    assert counts["after"] == counts["before"]       # the API's limit ends with the call


def test_the_count_can_be_set():
    assert _run(HANDMOCAP_BLAS_THREADS="2")["inside"] == [2]
    assert _run(OPENBLAS_NUM_THREADS="2")["variable"] == "2"   # the user's own setting is kept for later loads
