"""The per-epoch filtering loop shared by the estimators, and the rows of its table."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from filters.attitude import quaternion_canonical
from lightcurve.inversion.context import Context

__all__ = ["EpochEstimate", "epoch_row", "filter_epochs"]


@dataclass(frozen=True)
class EpochEstimate:
    """A filter's state after one measurement.

    Attributes
    ----------
    q : (4,) numpy.ndarray
        Attitude, inertial → body.
    omega : (3,) numpy.ndarray
        Body rates (rad/s).
    covariance : (n, n) numpy.ndarray
        Covariance of ``[δθ (rad), ω (rad/s)(, …)]``.
    predicted : float
        Predicted magnitude of the measurement.
    gated : bool
        The measurement was rejected by the innovation gate.
    probabilities : (S,) numpy.ndarray
        Probability of each candidate shape.
    """

    q: np.ndarray
    omega: np.ndarray
    covariance: np.ndarray
    predicted: float
    gated: bool
    probabilities: np.ndarray


def epoch_row(
    mjd: float, estimate: EpochEstimate, measured: float, names: Sequence[str] | None
) -> dict[str, Any]:
    """One row of the per-epoch table: ``mjd, q1..q4`` (sign-canonical), ``wx, wy, wz``,
    ``sigma_att_x/y/z`` (deg), ``sigma_wx/wy/wz`` (rad/s), ``predicted_mag, residual,
    gated`` and, with ``names``, ``p_<name>`` per shape."""
    q = quaternion_canonical(np.asarray(estimate.q, dtype=float))
    sigma = np.sqrt(np.clip(np.diag(estimate.covariance)[:6], 0.0, None))
    row = {"mjd": mjd}
    row.update({f"q{i + 1}": float(q[i]) for i in range(4)})
    row.update({f"w{a}": float(estimate.omega[i]) for i, a in enumerate("xyz")})
    row.update({f"sigma_att_{a}": math.degrees(sigma[i]) for i, a in enumerate("xyz")})
    row.update({f"sigma_w{a}": float(sigma[3 + i]) for i, a in enumerate("xyz")})
    row["predicted_mag"] = estimate.predicted
    row["residual"] = float(measured - estimate.predicted)
    row["gated"] = estimate.gated
    if names is not None:
        row.update({f"p_{n}": float(p) for n, p in zip(names, estimate.probabilities, strict=True)})
    return row


def filter_epochs(
    ctx: Context,
    *,
    predict: Callable[[float], None],
    update: Callable[[int], EpochEstimate],
    status: Callable[[], str] | None = None,
) -> pd.DataFrame:
    """Run a filter over every measurement in time order and tabulate its estimates.

    Parameters
    ----------
    ctx : Context
    predict : callable
        ``predict(dt)``: propagate the filter over ``dt`` seconds.
    update : callable
        ``update(k)``: process measurement ``k`` and return the state after it.
    status : callable
        Extra text of the progress messages (e.g. the effective sample size).

    Returns
    -------
    pandas.DataFrame
        One :func:`epoch_row` per measurement (``p_<shape>`` columns with several shapes).
    """
    model = ctx.model
    times, n = model.times, len(model)
    names = ctx.names if model.n_shapes > 1 else None
    rows = []
    for k in range(n):
        if k:
            predict(times[k] - times[k - 1])
        rows.append(epoch_row(model.mjd[k], update(k), model.magnitudes[k], names))
        if k % 50 == 0:
            ctx.report(
                0.3 + 0.7 * k / n, f"{ctx.method}: {k}/{n} measurements{status() if status else ''}"
            )
    return pd.DataFrame(rows)
