"""Relative positioning of a chaser (rover) to a cooperative target (base) from raw GNSS data.

The receiver functions of the multi-mode navigator's RGNSS module (Shi, Zhang, Li, Lang &
Zheng, *Relative navigation architecture for aerospace vehicles based on multimodal
measurement*, sec. 2.2.1.1): common-view selection (fewer than five common satellites → no
relative fix), code double-difference positioning with the highest satellite as reference,
ambiguity initialisation from carrier-phase double differences over several epochs (float
least squares, then LAMBDA, accepted by the ratio test and the success-rate bound), and
fixed carrier-phase positioning; plus relative velocity from time-differenced carrier phase,
cycle-slip detection with re-initialisation, and a carrier-smoothed code solution (Hatch
filter, :mod:`filters.gnss.smoothing`) that needs no integer ambiguity.

**Model** (epoch ``k``, ``m`` common satellites, reference ``q``; all in the week-start
inertial frame of :mod:`filters.gnss.constellation`). With the baseline
``b = x_rover − x_base`` linearised about ``b₀`` and ``A = −D U`` (``U`` the rover's unit
lines of sight, ``D`` the double-difference operator):

``y_P = DD P − DD ρ(b₀) = A δb + e_P``,   ``Q_P = Q_DD(σ_P²)``
``y_Φ = λ DD φ − DD ρ(b₀) = A δb + λ a + e_Φ``,   ``Q_Φ = Q_DD(σ_Φ²)``

with integer double-difference ambiguities ``a`` (cycles). The baseline changes every epoch
(kinematic positioning), the ambiguities do not, so each epoch adds to the ambiguity normal
equations its block with the epoch's baseline reduced out (Teunissen & Kleusberg 1998,
ch. 8; Strang & Borre 1997, ch. 14):

``N_bb = Aᵀ (W_P + W_Φ) A``,  ``N_ba = λ Aᵀ W_Φ``,  ``N_aa = λ² W_Φ``,
``n_b = Aᵀ (W_P y_P + W_Φ y_Φ)``,  ``n_a = λ W_Φ y_Φ``,
``N̄ += N_aa − N_ab N_bb⁻¹ N_ba``,  ``n̄ += n_a − N_ab N_bb⁻¹ n_b``  (``W = Q⁻¹``).

The float ambiguities are ``â = N̄⁻¹ n̄`` with ``Q_â = N̄⁻¹``; LAMBDA gives the integer
candidates (:mod:`filters.gnss.lambda_`), and the fix is accepted when the ratio test and the
bootstrapped success rate pass. Satellites that rise later get new ambiguities, resolved
conditionally on the ones already fixed; a change of reference satellite re-expresses the
ambiguities (``a'_s = a_s − a_{q'}``, ``a'_q = −a_{q'}``) without losing them.

**Cycle slips.** Between consecutive epochs the time-differenced double-differenced phase
``Δy = A_k δb + λ Δa + ε`` is free of ambiguities unless a slip occurred; with ``m ≥ 5`` it
has redundancy ``m − 4``. A global χ² test on its least-squares residuals detects slips, and
the w-test of Baarda's data snooping identifies the slipping satellite (a slip on the
reference shifts every double difference); its ambiguity is re-initialised, and all of them
if the reference slipped or the redundancy runs out. The same least squares gives the relative
velocity ``δb / Δt`` (mean over the interval). The fixed solution is validated each epoch by
a χ² test of its phase residuals; a failure (a wrong fix or an undetected slip) re-initialises
all ambiguities.

**Code solutions.** The snapshot code solution is the least squares of one epoch's code
double differences (``Q_P`` above); its error is the single-difference code noise
``√2 σ_P`` times the dilution of precision of the common-view geometry, independent from
epoch to epoch. The carrier-smoothed solution is the same least squares of the Hatch-filtered
single-difference codes, whose variances ``v_s`` (:mod:`filters.gnss.smoothing`: about
``2 σ_P² / n`` after ``n`` epochs) give ``Q = diag(v_s, s ≠ q) + v_q 1 1ᵀ``. A satellite's
channel restarts when it enters common view, when a cycle slip is detected on it, and every
channel restarts when the carrier's continuity cannot be checked (no previous epoch, too few
satellites, a slip on the reference or the fixed solution failing its residual test). The
smoothed solution is what the navigator falls back on without a fix (``code_position``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np
from scipy.stats import chi2

from filters.gnss.ambiguity import AmbiguityNormals
from filters.gnss.constellation import SPEED_OF_LIGHT, Constellation
from filters.gnss.differencing import (
    MIN_COMMON_SATELLITES,
    double_difference_covariance,
    double_differences,
    reference_satellite,
)
from filters.gnss.lambda_ import lambda_method
from filters.gnss.measurements import L1_WAVELENGTH, elevations
from filters.gnss.smoothing import CarrierSmoothing
from filters.gnss.snapshot import (
    double_difference_geometry,
    epoch_normal_equations,
    single_point_position,
)

__all__ = [
    "AmbiguityNormals",
    "RelativeGnssConfig",
    "RelativeGnssSolver",
    "RelativeSolution",
    "double_difference_geometry",
    "epoch_normal_equations",
    "fixed_ambiguities_correct",
    "single_point_position",
]


@dataclass(frozen=True, kw_only=True)
class RelativeGnssConfig:
    """Settings of :class:`RelativeGnssSolver` (SI units).

    Attributes
    ----------
    code_sigma, phase_sigma : float
        Assumed 1σ of undifferenced code and phase measurements (m); they set the weights.
    wavelength : float
        Carrier wavelength (m).
    ratio_threshold : float
        Ratio-test critical value ``c``: accept when ``‖â − ǎ₂‖² / ‖â − ǎ₁‖² ≥ c``.
    min_success_rate : float
        Least bootstrapped success rate of the decorrelated float ambiguities for a fix.
    min_satellites : int
        Fewest common satellites for a relative fix (five in the paper).
    slip_false_alarm : float
        False-alarm probability of the cycle-slip χ² test.
    fix_false_alarm : float
        False-alarm probability of the χ² test of the fixed solution's residuals.
    smoothing_window : float
        Window of the carrier smoothing of the code (s); ``0`` leaves the code raw.
    """

    code_sigma: float = 0.5
    phase_sigma: float = 0.003
    wavelength: float = L1_WAVELENGTH
    ratio_threshold: float = 3.0
    min_success_rate: float = 0.999
    min_satellites: int = MIN_COMMON_SATELLITES
    slip_false_alarm: float = 1e-4
    fix_false_alarm: float = 1e-5
    smoothing_window: float = 100.0

    def __post_init__(self) -> None:
        for name in ("code_sigma", "phase_sigma", "wavelength"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)}")
        if not self.ratio_threshold >= 1:
            raise ValueError(f"ratio_threshold must be >= 1, got {self.ratio_threshold}")
        if not 0 <= self.min_success_rate < 1:
            raise ValueError(f"min_success_rate must be in [0, 1), got {self.min_success_rate}")
        if self.min_satellites < 5:
            raise ValueError(f"min_satellites must be >= 5, got {self.min_satellites}")
        if not self.smoothing_window >= 0:
            raise ValueError(f"smoothing_window must be >= 0 s, got {self.smoothing_window}")
        for name in ("slip_false_alarm", "fix_false_alarm"):
            if not 0 < getattr(self, name) < 1:
                raise ValueError(f"{name} must be in (0, 1), got {getattr(self, name)}")


@dataclass(frozen=True, kw_only=True)
class RelativeSolution:
    """One epoch of :class:`RelativeGnssSolver` (inertial frame, SI units).

    Attributes
    ----------
    time : float
        GPS time (s).
    status : {"none", "code", "float", "fixed"}
        Best solution available: none (fewer than ``min_satellites`` in common view), code
        double differences only, float carrier phase, fixed carrier phase.
    satellites : int
        Satellites in common view.
    reference : int or None
        PRN of the reference satellite.
    position, covariance : (3,), (3, 3) numpy.ndarray
        Baseline ``x_rover − x_base`` of the best solution and its covariance (NaN for none).
    code_position, code_covariance : (3,), (3, 3) numpy.ndarray
        Ambiguity-free solution: double differences of the carrier-smoothed code (the
        navigator's fallback without a fix); the snapshot solution when
        ``smoothing_window`` is 0 or every channel has just restarted.
    snapshot_position, snapshot_covariance : (3,), (3, 3) numpy.ndarray
        Raw code double-difference solution of this epoch alone (independent from epoch to
        epoch).
    velocity, velocity_covariance : (3,), (3, 3) numpy.ndarray
        Mean relative velocity since the previous epoch from time-differenced carrier phase
        (NaN when unavailable).
    fixed : int
        Number of fixed double-difference ambiguities.
    ratio, success_rate : float
        Ratio and bootstrapped success rate of this epoch's LAMBDA call (NaN without one).
    slips : tuple of int
        PRNs whose ambiguities were re-initialised after a detected cycle slip.
    ambiguities : dict[int, int]
        Fixed double-difference ambiguities by PRN (reference: ``reference``).
    smoothing : dict[int, int]
        Epochs since each satellite's carrier smoothing (re)started, this one included.
    message : str
        Why there is no fix, or which resets happened.
    """

    time: float
    status: str
    satellites: int
    reference: int | None
    position: np.ndarray
    covariance: np.ndarray
    code_position: np.ndarray
    code_covariance: np.ndarray
    velocity: np.ndarray
    velocity_covariance: np.ndarray
    snapshot_position: np.ndarray = field(default_factory=lambda: _NAN3)
    snapshot_covariance: np.ndarray = field(default_factory=lambda: _NAN33)
    fixed: int = 0
    ratio: float = float("nan")
    success_rate: float = float("nan")
    slips: tuple[int, ...] = ()
    ambiguities: dict[int, int] = field(default_factory=dict)
    smoothing: dict[int, int] = field(default_factory=dict)
    message: str = ""


@lru_cache(maxsize=512)
def _chi2_limit(false_alarm: float, dof: int) -> float:
    """Critical value of the χ² test with ``dof`` degrees of freedom."""
    return float(chi2.ppf(1.0 - false_alarm, dof))


_NAN3 = np.full(3, np.nan)
_NAN33 = np.full((3, 3), np.nan)


class RelativeGnssSolver:
    """Epoch-by-epoch relative GNSS of a rover (chaser) with respect to a base (target).

    Parameters
    ----------
    constellation : Constellation
        Broadcast orbits and clocks (the same almanac the receivers use).
    config : RelativeGnssConfig, optional

    Examples
    --------
    >>> solver = RelativeGnssSolver(constellation)
    >>> for k, t in enumerate(obs.times):
    ...     sol = solver.process(t, obs.prn, obs.code[0, k], obs.phase[0, k],
    ...                          obs.code[1, k], obs.phase[1, k])
    """

    def __init__(self, constellation: Constellation, config: RelativeGnssConfig | None = None):
        self.constellation = constellation
        self.config = config or RelativeGnssConfig()
        self._index = {int(p): i for i, p in enumerate(constellation.prn)}
        self.reset()
        self._base: np.ndarray | None = None

    def reset(self) -> None:
        """Forget all ambiguities, the previous epoch and the carrier smoothing."""
        self.ambiguities: AmbiguityNormals | None = None
        self._previous: dict[str, Any] | None = None
        self.smoothing = CarrierSmoothing(self.config.smoothing_window)

    # ------------------------------------------------------------------ helpers
    def _weights(self, m: int, ref: int) -> tuple[np.ndarray, np.ndarray]:
        c = self.config
        ones = np.ones(m)
        return (
            double_difference_covariance(c.code_sigma**2 * ones, c.code_sigma**2 * ones, ref),
            double_difference_covariance(c.phase_sigma**2 * ones, c.phase_sigma**2 * ones, ref),
        )

    def _code_solution(self, sat, vel, ref, base, sd_code, *, baseline, q_code):
        """Iterated least squares of code double differences for the baseline."""
        w = np.linalg.inv(q_code)
        for _ in range(4):
            geo, _, design = double_difference_geometry(sat, vel, ref, base, baseline)
            y = double_differences(sd_code - geo, ref)
            cov = np.linalg.inv(design.T @ w @ design)
            step = cov @ design.T @ w @ y
            baseline = baseline + step
            if np.linalg.norm(step) < 1e-4:
                break
        return baseline, cov

    def _detect_slips(self, y, design, q) -> tuple[list[int], np.ndarray, np.ndarray]:
        """χ² test of time-differenced DD phase residuals with w-test identification.

        Returns the indices of the rows (or ``-1`` for the reference) judged to have slipped,
        the least-squares baseline change and its covariance from the remaining rows.
        """
        rows = np.arange(len(y))
        flagged: list[int] = []
        while True:
            a, qq, yy = design[rows], q[np.ix_(rows, rows)], y[rows]
            w = np.linalg.inv(qq)
            cov = np.linalg.inv(a.T @ w @ a)
            delta = cov @ a.T @ w @ yy
            r = yy - a @ delta
            dof = len(rows) - 3
            if dof < 1:
                return [*flagged, -1], delta, cov
            if r @ w @ r <= _chi2_limit(self.config.slip_false_alarm, dof):
                return flagged, delta, cov
            q_r = qq - a @ cov @ a.T
            wr = w @ r
            candidates = np.vstack([np.eye(len(rows)), -np.ones(len(rows))])
            num = candidates @ wr
            den = np.sqrt(np.einsum("ij,jk,ik->i", candidates, w @ q_r @ w, candidates))
            best = int(np.argmax(np.abs(num) / np.maximum(den, 1e-300)))
            if best == len(rows):
                return [*flagged, -1], delta, cov
            flagged.append(int(rows[best]))
            rows = np.delete(rows, best)

    def _none(self, t: float, m: int, message: str) -> RelativeSolution:
        return RelativeSolution(
            time=t,
            status="none",
            satellites=m,
            reference=None,
            position=_NAN3,
            covariance=_NAN33,
            code_position=_NAN3,
            code_covariance=_NAN33,
            velocity=_NAN3,
            velocity_covariance=_NAN33,
            message=message,
        )

    # ------------------------------------------------------------------ main entry
    def process(
        self,
        t: float,
        prn: Any,
        base_code: Any,
        base_phase: Any,
        rover_code: Any,
        rover_phase: Any,
    ) -> RelativeSolution:
        """Process one epoch of raw measurements of both receivers.

        Parameters
        ----------
        t : float
            GPS time (s).
        prn : (n,) array_like of int
            Satellites of the measurement arrays.
        base_code, rover_code : (n,) array_like
            Pseudoranges (m); NaN where not tracked.
        base_phase, rover_phase : (n,) array_like
            Carrier phases (cycles); NaN where not tracked.

        Returns
        -------
        RelativeSolution
        """
        cfg = self.config
        lam = cfg.wavelength
        prn = np.asarray(prn, dtype=int)
        bc, bp = np.asarray(base_code, float), np.asarray(base_phase, float)
        rc, rp = np.asarray(rover_code, float), np.asarray(rover_phase, float)
        known = np.array([p in self._index for p in prn])
        base_ok = known & np.isfinite(bc)
        common = base_ok & np.isfinite(bp) & np.isfinite(rc) & np.isfinite(rp)
        m = int(common.sum())
        if m < cfg.min_satellites:
            self.reset()
            return self._none(
                t, m, f"{m} satellites in common view, fewer than {cfg.min_satellites}: "
                "no relative fix"
            )  # fmt: skip

        # Satellite states at the epoch; base position by single point positioning.
        all_index = np.array([self._index[p] for p in prn[base_ok]])
        sat_all, vel_all = self.constellation.states(t, all_index)
        corrected = bc[base_ok] + SPEED_OF_LIGHT * self.constellation.clock_offsets(t, all_index)
        base, _ = single_point_position(sat_all, vel_all, corrected, initial=self._base)
        self._base = base
        prns = prn[common]
        in_common = common[base_ok]
        sat, vel = sat_all[in_common], vel_all[in_common]
        el = elevations(base, sat)

        amb = self.ambiguities
        previous = self._previous
        lookup = {int(p): i for i, p in enumerate(prns)}
        messages: list[str] = []
        if amb is not None:
            # Keep the reference while it is in view; otherwise the highest satellite whose
            # ambiguity is already a parameter (so the others can be re-expressed).
            if amb.reference in lookup:
                ref = lookup[amb.reference]
            else:
                candidates = np.array([int(p) in amb.prns for p in prns])
                if candidates.any():
                    ref = reference_satellite(el, allowed=candidates)
                    amb.drop([p for p in amb.prns if p not in lookup and p != int(prns[ref])])
                    amb.change_reference(int(prns[ref]))
                    messages.append(f"reference changed to PRN {int(prns[ref])}")
                else:
                    amb = None
                    messages.append("reference lost: ambiguities re-initialised")
        if amb is None:
            ref = reference_satellite(el)
            amb = AmbiguityNormals(int(prns[ref]))
            previous = None
        amb.drop([p for p in amb.prns if p not in lookup])
        others = np.delete(prns, ref)
        amb.add(others)

        sd_code = rc[common] - bc[common]
        sd_phase = lam * (rp[common] - bp[common])
        q_code, q_phase = self._weights(m, ref)

        # Code-only double-difference solution (also the linearisation point).
        start = previous["baseline"] if previous is not None else np.zeros(3)
        b_code, c_code = self._code_solution(
            sat, vel, ref, base, sd_code, baseline=start, q_code=q_code
        )
        b0 = previous["baseline"] if previous is not None else b_code
        geo, jacobian, design = double_difference_geometry(sat, vel, ref, base, b0)

        # Cycle slips and velocity from time-differenced carrier phase.
        velocity, velocity_cov, slipped = _NAN3, _NAN33, []
        continuous = np.zeros(m, dtype=bool)  # carrier checked continuous since last epoch
        if previous is not None:
            both = np.array([int(p) in previous["sd_phase"] for p in others])
            if both.sum() >= 4:
                rows = np.flatnonzero(both)
                keep = np.append(np.delete(np.arange(m), ref)[rows], ref)
                keep_prn = prns[keep]
                d_sd = np.array(
                    [
                        sd_phase[lookup[p]] - previous["sd_phase"][p]
                        - (geo[lookup[p]] - previous["geometry"][p])
                        for p in keep_prn
                    ]
                )  # fmt: skip
                y_td = double_differences(d_sd, len(keep) - 1)
                q_td = 2.0 * q_phase[np.ix_(rows, rows)]
                flagged, delta, cov = self._detect_slips(y_td, design[rows], q_td)
                dt = t - previous["time"]
                if -1 in flagged:
                    amb = AmbiguityNormals(int(prns[ref]))
                    amb.add(others)
                    slipped = [int(p) for p in prns]
                    messages.append(
                        "cycle slip on the reference or not identifiable: all ambiguities "
                        "re-initialised"
                    )
                else:
                    slipped = [int(others[rows[i]]) for i in flagged]
                    amb.reset(slipped)
                    continuous[keep] = True
                    continuous[[lookup[p] for p in slipped]] = False
                    velocity, velocity_cov = delta / dt, cov / dt**2
                    if slipped:
                        messages.append(f"cycle slips on PRN {slipped}: re-initialised")
        self.ambiguities = amb

        # Accumulate the epoch's ambiguity normal equations.
        y_code = double_differences(sd_code - geo, ref)
        y_phase = double_differences(sd_phase - geo, ref)
        ne = epoch_normal_equations(design, y_code, y_phase, q_code, q_phase, lam)
        amb.accumulate(ne["reduced_normal"], ne["reduced_rhs"], others)
        order = amb.position(others)  # parameter index of each double difference

        # Fix what is not fixed yet (conditionally on what is).
        ratio = success = float("nan")
        free = np.flatnonzero(np.isnan(amb.fixed))
        if free.size:
            a_float, q_float = amb.float_solution(free)
            estimate = lambda_method(a_float, q_float)
            ratio, success = estimate.ratio, estimate.success_rate
            if estimate.accepted(cfg.ratio_threshold, cfg.min_success_rate):
                amb.fixed[free] = estimate.best

        # Best solution of the epoch.
        fixed_rows = np.flatnonzero(np.isfinite(amb.fixed[order]))
        status, position, covariance = "code", b_code, c_code
        if fixed_rows.size >= cfg.min_satellites - 1:
            a_fix = amb.fixed[order][fixed_rows]
            f = fixed_rows
            w_c = np.linalg.inv(q_code)
            w_f = np.linalg.inv(q_phase[np.ix_(f, f)])
            y_f = y_phase[f] - lam * a_fix
            normal = design.T @ w_c @ design + design[f].T @ w_f @ design[f]
            cov = np.linalg.inv(normal)
            delta = cov @ (design.T @ w_c @ y_code + design[f].T @ w_f @ y_f)
            r_c, r_f = y_code - design @ delta, y_f - design[f] @ delta
            statistic = r_c @ w_c @ r_c + r_f @ w_f @ r_f
            dof = len(y_code) + len(f) - 3
            if statistic <= _chi2_limit(cfg.fix_false_alarm, dof):
                status, position, covariance = "fixed", b0 + delta, cov
            else:
                amb = AmbiguityNormals(int(prns[ref]))
                amb.add(others)
                self.ambiguities = amb
                continuous[:] = False  # perhaps an undetected slip
                messages.append("fixed solution failed its residual test: re-initialised")
        if status == "code" and amb.epochs > 0:
            a_hat, q_hat = amb.float_solution(np.arange(len(amb.prns)), conditional=False)
            a_hat, q_hat = a_hat[order], q_hat[np.ix_(order, order)]
            nbb_inv = np.linalg.inv(ne["N_bb"])
            gain = nbb_inv @ ne["N_ba"]
            status, position = "float", b0 + nbb_inv @ ne["n_b"] - gain @ a_hat
            covariance = nbb_inv + gain @ q_hat @ gain.T

        # Carrier-smoothed code (Hatch filter of single differences) and its solution.
        smoothed, variance, smoothed_epochs = self.smoothing.update(
            t, prns, sd_code, sd_phase, continuous,
            code_variance=2.0 * cfg.code_sigma**2,
            phase_variance=2.0 * cfg.phase_sigma**2,
        )  # fmt: skip
        b_smooth, c_smooth = self._code_solution(
            sat, vel, ref, base, smoothed,
            baseline=b_code,
            q_code=double_difference_covariance(variance, np.zeros(m), ref),
        )  # fmt: skip

        # Geometry at the epoch's estimate, for the next epoch's time differences.
        geometry = geo + jacobian @ (position - b0)
        self._previous = {
            "time": t,
            "baseline": position,
            "sd_phase": dict(zip(prns.tolist(), sd_phase, strict=True)),
            "geometry": dict(zip(prns.tolist(), geometry, strict=True)),
        }
        fixed_map = {
            int(p): int(a) for p, a in zip(amb.prns, amb.fixed, strict=True) if np.isfinite(a)
        }
        return RelativeSolution(
            time=t,
            status=status,
            satellites=m,
            reference=int(prns[ref]),
            position=position,
            covariance=covariance,
            code_position=b_smooth,
            code_covariance=c_smooth,
            velocity=velocity,
            velocity_covariance=velocity_cov,
            snapshot_position=b_code,
            snapshot_covariance=c_code,
            fixed=len(fixed_map),
            ratio=ratio,
            success_rate=success,
            slips=tuple(slipped),
            ambiguities=fixed_map,
            smoothing=dict(zip(prns.tolist(), smoothed_epochs.tolist(), strict=True)),
            message="; ".join(messages),
        )


def fixed_ambiguities_correct(
    solution: RelativeSolution, prn: Any, base_ambiguity: Any, rover_ambiguity: Any
) -> bool:
    """Whether a solution's fixed double-difference integers equal the simulated truth.

    Parameters
    ----------
    solution : RelativeSolution
    prn : (n,) array_like of int
        Satellites of the truth arrays.
    base_ambiguity, rover_ambiguity : (n,) array_like of int
        True undifferenced ambiguities ``N`` of the epoch.
    """
    where = {int(p): i for i, p in enumerate(np.asarray(prn))}
    sd = np.asarray(rover_ambiguity, dtype=np.int64) - np.asarray(base_ambiguity, dtype=np.int64)
    q = where[solution.reference]
    return all(sd[where[p]] - sd[q] == a for p, a in solution.ambiguities.items())
