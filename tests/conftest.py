"""Test-session settings shared by every test module."""

import compileall
import importlib.util
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from functools import partial

import pytest
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
    import torch

    torch.set_num_threads(1)
    for variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[variable] = "1"


# ------------------------------------------------------------------ balancing the xdist workers
# CPU seconds of the longest test modules on the CI machine (first tests of a fresh clone:
# numba's compilation included), measured with
# `CI_TIME_LOG=… python -m pytest -n 2 --dist worksteal -p benchmarks.ci_time` (see
# benchmarks/ci_time.py); a node-id prefix may name one test or parametrised case. Only the
# order of the tests depends on these figures: a stale or missing entry makes the run less
# balanced, never wrong.
LONG_RUNNING_S: dict[str, float] = {
    "tests/notebooks/test_notebooks.py": 154.0,
    "tests/lightcurve/test_invert_batch.py": 58.0,
    "tests/lightcurve/analysis/test_glint.py": 56.0,
    "tests/lightcurve/photometry/test_kernels.py": 55.0,
    "tests/lightcurve/inversion/test_inversion.py": 46.0,
    "tests/lightcurve/test_cli_help.py": 30.0,
    "tests/lightcurve/analysis/test_convex.py": 27.0,
    "tests/lightcurve/inversion/test_pf_shapes.py": 25.0,
    "tests/lightcurve/test_batch.py": 17.0,
    "tests/lightcurve/inversion/test_readme_tour_pf.py": 15.0,
    "tests/lightcurve/test_cli_shapes.py": 15.0,
    "tests/filters/navigation/test_monocular.py": 12.0,
    "tests/filters/navigation/test_lander.py": 11.0,
    "tests/filters/navigation/test_relnav.py": 11.0,
}


@pytest.hookimpl(trylast=True)  # after pytest's own reordering by fixture scope
def pytest_collection_modifyitems(config, items):
    """Start the long tests first on every xdist worker, spread over the workers.

    ``--dist worksteal`` hands worker k the k-th contiguous share of the collection and lets
    an idle worker steal the end of another's queue. The long modules (``LONG_RUNNING_S``)
    are dealt to the shares so their CPU time is balanced, longest first, and head their
    share; the other tests keep their order and fill the shares to xdist's counts. A test
    module stays in one piece, so its module-scoped fixtures are built once.
    """
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    if workers < 2 or not LONG_RUNNING_S:
        return
    blocks: dict[str, list] = {}
    short = []
    for item in items:
        key = next((k for k in LONG_RUNNING_S if item.nodeid.startswith(k)), None)
        if key is None:
            short.append(item)
        else:
            blocks.setdefault(key, []).append(item)
    shares: list[list] = [[] for _ in range(workers)]
    load = [0.0] * workers
    for key in sorted(blocks, key=LONG_RUNNING_S.__getitem__, reverse=True):
        k = load.index(min(load))
        shares[k].extend(blocks[key])
        load[k] += LONG_RUNNING_S[key]
    ordered = []
    remaining = len(items)
    for k, share in enumerate(shares):
        size = remaining // (workers - k)  # xdist's first hand-out to each worker
        fill = max(0, size - len(share))
        ordered += share + short[:fill]
        del short[:fill]
        remaining -= len(share) + fill
    items[:] = ordered + short


# ------------------------------------------------------- bytecode compiled once, before the workers
# The README's installs skip compiling bytecode (`pip install --no-compile`): Python compiles a
# module on its first import and caches it in `__pycache__`. In a fresh environment the
# processes that start together — the xdist workers collecting the same test modules, the batch
# and Dask workers a test starts — each compile the same modules (collection alone: 34 s of CPU
# cold, 12 s with the bytecode in place). The controller therefore compiles, before the workers
# start, the packages of which the suite imports most (≥ 0.5 MB of imported source each on a
# full run), one process per worker; test folders are skipped. A package missing from the list
# compiles on first import as before: the list decides speed, never results.
BYTECODE_PACKAGES = (
    "torch", "sympy", "scipy", "pandas", "astropy", "numba", "matplotlib", "networkx", "numpy",
    "debugpy", "distributed", "trimesh", "setuptools", "mpmath", "_pytest", "hypothesis",
    "IPython", "tornado", "erfa", "PIL", "dask", "brdf", "shapes", "filters", "lightcurve",
)  # fmt: skip
_NOT_IMPORTED = {"tests", "test", "testing", "__pycache__"}


def _stale_sources(packages: tuple[str, ...]) -> list[str]:
    """Source files of ``packages`` whose cached bytecode is missing or older than the source.

    Folders where Python could not write the bytecode either (a read-only installation) are
    skipped.
    """
    stale = []
    for name in packages:
        spec = importlib.util.find_spec(name)
        for root in (spec.submodule_search_locations or []) if spec else []:
            for folder, subfolders, files in os.walk(root):
                subfolders[:] = [d for d in subfolders if d not in _NOT_IMPORTED]
                cache = os.path.join(folder, "__pycache__")
                if not os.access(cache if os.path.isdir(cache) else folder, os.W_OK):
                    continue
                for file in files:
                    if not file.endswith(".py"):
                        continue
                    source = os.path.join(folder, file)
                    try:
                        cached = importlib.util.cache_from_source(source)
                        if os.stat(cached).st_mtime >= os.stat(source).st_mtime:
                            continue
                    except OSError:
                        pass
                    stale.append(source)
    return stale


def pytest_configure(config):
    """On the xdist controller, compile the suite's heavy dependencies once, in parallel."""
    workers = getattr(config.option, "numprocesses", None)
    if (
        not isinstance(workers, int)
        or workers < 2
        or os.environ.get("PYTEST_XDIST_WORKER")
        or sys.dont_write_bytecode
    ):
        return
    stale = _stale_sources(BYTECODE_PACKAGES)
    if stale:
        processes = min(workers, os.cpu_count() or 1)
        with ProcessPoolExecutor(processes) as pool:  # small chunks: the processes end together
            compile_file = partial(compileall.compile_file, quiet=2)
            list(pool.map(compile_file, stale, chunksize=1 + len(stale) // (64 * processes)))
