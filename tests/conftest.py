"""Test-session settings shared by every test module."""

import os

import torch

# pytest-xdist runs one worker per core; torch's own intra-op threads on top of that
# oversubscribe the machine (each elementwise op then waits on spinning threads).
if os.environ.get("PYTEST_XDIST_WORKER"):
    torch.set_num_threads(1)
