"""Inertial reference directions shared by the attitude-estimation tests."""

from __future__ import annotations

import torch

#: Two non-parallel unit inertial directions: a sensor that sees both in the body frame
#: leaves no rotation unobservable.
VECTORS = torch.tensor([[0.48, -0.6, 0.64], [0.0, 0.6, 0.8]], dtype=torch.float64)
