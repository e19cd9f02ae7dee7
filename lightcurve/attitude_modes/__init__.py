"""Attitude-mode identification: is the object held by a control system, or tumbling?

For each candidate shape, every stabilised hypothesis — a profile of
:mod:`lightcurve.photometry.profiles` (``inertial``, ``nadir``, ``nadir yaw-steering``,
``sun-pointing``) with an unknown fixed offset — is fitted to the whole arc, and weighed
against the tumbling hypothesis (a torque-free initial state ``[q₀, ω₀]``, found by
today's search and filter, then fitted to the whole arc by batched Levenberg–Marquardt).

Model comparison by the Laplace approximation of the evidence (MacKay 2003, "Information
Theory, Inference, and Learning Algorithms", ch. 28): for a hypothesis ``H`` with ``k``
parameters ``θ``, best fit ``θ̂``, whitened residuals of Jacobian ``J`` and prior ``p(θ)``,

``ln Z_H ≈ −½ χ²(θ̂) + ln p(θ̂) + (k/2) ln 2π − ½ ln det(JᵀJ + P)``

(``P`` the prior's precision, which bounds the determinant along directions the data do not
see). This is the BIC's ``−½ k ln n`` made exact for the priors at hand: a parameter the data
pin down to ``σ`` inside a prior range ``Δ`` costs ``ln(Δ/σ)``. The priors:

* offsets of the ``nadir`` and ``sun-pointing`` profiles: isotropic normal, ``σ_off`` per
  axis (default 10°, so offsets of a few degrees cost little);
* the ``inertial`` attitude: uniform on SO(3), density ``G/(8π²)`` in small-angle
  coordinates (``G`` the order of the shape's rotational symmetry group, whose equivalent
  attitudes are all fits);
* tumbling: the same uniform attitude and rates uniform in the ball ``|ω| ≤ ω_max``.

A stabilised object is then fitted as well by the tumbling hypothesis (``ω`` ≈ the
profile's slow turn) but pays for six free parameters with wide priors (about 25 nats more
on a night of GEO photometry), and a tumbling object cannot be fitted by any profile.
The hypotheses' prior probabilities are ½ for tumbling and ½ shared equally by the
stabilised profiles (shapes equally likely); the posterior of a mode sums over shapes.

The offset of a profile is fitted by the local least-squares step from several starts:
the distinct valleys of a coarse scan of the prior's range, then shells around the best
optimum at fractions of the scan's spacing (glints leave side valleys finer than any
affordable scan; :mod:`lightcurve.attitude_modes.offsets`).

A principal direction of a fitted offset whose Laplace 1σ, or whose 95 % profile-likelihood
interval's half-width over 1.96, exceeds ``weak_sigma_deg`` (the turn about the Sun line of
a Sun-pointing body whose lit face is perpendicular to it, say) is reported as a weak axis
with that interval (:class:`WeakAxis`), so the offset is a point across such axes and an
interval along them.

The winning offset (the most probable stabilised profile and shape) is also sampled from
its posterior by an ensemble MCMC (:mod:`lightcurve.attitude_modes.posterior`): where glints
curve the ``χ²`` valley the Laplace 1σ understates the spread, and the sampled 68 % and
95 % intervals and joint regions hold at their stated rate; ``laplace_ok`` says whether the
two agree.

A stabilised hypothesis must also pass a consistency test: ``χ²`` at most the
``consistency_level`` quantile of ``χ²`` with ``n − k`` degrees of freedom. One that fails
is discarded (a profile that does not reproduce the light curve to within its noise is no
evidence of control); the tumbling hypothesis is never discarded, so an object that nothing
fits is reported ``tumbling`` — not shown to be stabilised — with ``none_fits`` set.

Modules: :mod:`~lightcurve.attitude_modes.identify` (the entry point),
:mod:`~lightcurve.attitude_modes.hypotheses` (stabilised and tumbling fits),
:mod:`~lightcurve.attitude_modes.offsets` (offset fit and its multi-start),
:mod:`~lightcurve.attitude_modes.weak_axes` (weak axes and their intervals),
:mod:`~lightcurve.attitude_modes.posterior` (the sampled posterior of the winning offset),
:mod:`~lightcurve.attitude_modes.evidence` (Laplace evidence, consistency, mode posterior),
:mod:`~lightcurve.attitude_modes.results` (the outcome types).
"""

from __future__ import annotations

from lightcurve.attitude_modes.hypotheses import MODE_HYPOTHESES
from lightcurve.attitude_modes.identify import identify_attitude_mode, offset_error_deg
from lightcurve.attitude_modes.results import (
    TUMBLING,
    ModeHypothesis,
    ModeIdentification,
    WeakAxis,
)

__all__ = [
    "MODE_HYPOTHESES",
    "TUMBLING",
    "ModeHypothesis",
    "ModeIdentification",
    "WeakAxis",
    "identify_attitude_mode",
    "offset_error_deg",
]
