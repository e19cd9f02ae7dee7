"""Batched covariance square roots, including degenerate and non-converging input."""

import numpy as np
import torch

from filters.linalg import covariance_root


def test_root_reproduces_full_rank_and_singular_covariances():
    rng = np.random.default_rng(0)
    a = torch.as_tensor(rng.normal(size=(5, 6, 6)))
    full = a @ a.transpose(-1, -2)
    singular = torch.zeros(6, 6, dtype=torch.float64)
    singular[:2, :2] = torch.tensor([[4.0, 2.0], [2.0, 1.0]])  # rank 1
    c = torch.cat([full, singular[None]])
    root = covariance_root(c)
    assert torch.allclose(root @ root.transpose(-1, -2), c, atol=1e-10)


def test_svd_fallback_when_the_eigensolver_fails(monkeypatch):
    def failing(_):
        raise torch.linalg.LinAlgError("linalg.eigh: failed to converge (error code: 5)")

    rng = np.random.default_rng(1)
    a = torch.as_tensor(rng.normal(size=(3, 6, 6)))
    d = torch.diag(
        torch.tensor([1e-3] * 3 + [1e-5] * 3, dtype=torch.float64)
    )  # rad and rad/s scales
    c = d @ a @ a.transpose(-1, -2) @ d
    monkeypatch.setattr(torch.linalg, "eigh", failing)
    root = covariance_root(c)
    scale = torch.sqrt(torch.diagonal(c, dim1=-2, dim2=-1))
    error = (root @ root.transpose(-1, -2) - c) / (scale[..., :, None] * scale[..., None, :])
    assert float(error.abs().max()) < 1e-12
