"""Machine description printed with every benchmark's JSON."""

from __future__ import annotations

import os
import platform

import numpy as np


def machine_info() -> dict[str, object]:
    """Processor, core count, Python, numpy and torch versions, and torch's thread count."""
    import torch

    return {
        "processor": platform.processor() or platform.machine(),
        "cpu_count": os.cpu_count(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "torch": torch.__version__,
        "torch_threads": torch.get_num_threads(),
        "cuda": torch.cuda.is_available(),
    }
