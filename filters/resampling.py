"""Systematic resampling of weighted particles (Kitagawa 1996, "Monte Carlo filter and
smoother for non-Gaussian nonlinear state space models"), optionally within consecutive
blocks (the components of a mixture, Vermaak, Doucet & Pérez 2003)."""

from __future__ import annotations

import torch

__all__ = ["systematic_resample"]


def systematic_resample(
    weights: torch.Tensor, generator: torch.Generator, counts: torch.Tensor | None = None
) -> torch.Tensor:
    """Indices drawn by systematic resampling, one uniform offset per block.

    Parameters
    ----------
    weights : (N,) tensor
        Weights normalised within each block.
    generator : torch.Generator
    counts : (C,) tensor, optional
        Sizes of consecutive blocks resampled within themselves (mixture components);
        omitted: one block of all N.

    Returns
    -------
    (N,) long tensor
        Each slot's source index, inside the slot's own block.
    """
    n = len(weights)
    counts = weights.new_full((1,), n) if counts is None else counts.to(weights.dtype)
    block = torch.repeat_interleave(torch.arange(len(counts)), counts.long())
    starts = torch.cumsum(counts, dim=0) - counts
    cumulative = torch.cumsum(weights, dim=0)
    before = torch.cat([cumulative.new_zeros(1), cumulative])[starts.long()]
    offsets = torch.rand(len(counts), generator=generator, dtype=weights.dtype)
    slot = torch.arange(n, dtype=weights.dtype)
    positions = before[block] + (offsets[block] + slot - starts[block]) / counts[block]
    drawn = torch.searchsorted(cumulative, positions)
    first, last = starts[block].long(), (starts[block] + counts[block] - 1).long()
    return torch.minimum(torch.maximum(drawn, first), last)
