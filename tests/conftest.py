"""Test-session settings shared by every test module."""

import os

import torch
from hypothesis import settings

# Property-based tests draw their examples from a fixed seed: the same examples on every run
# and every machine (a failure is reproducible, never a flake of the draw).
settings.register_profile("deterministic", derandomize=True, print_blob=True)
settings.load_profile("deterministic")

# pytest-xdist runs one worker per core; torch's and BLAS's own threads on top of that
# oversubscribe the machine (each elementwise op then waits on spinning threads). The
# environment variables reach the processes the tests start too (notebook kernels, batch
# workers, Dask workers), which read them when they import torch or numpy.
if os.environ.get("PYTEST_XDIST_WORKER"):
    torch.set_num_threads(1)
    for variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[variable] = "1"
