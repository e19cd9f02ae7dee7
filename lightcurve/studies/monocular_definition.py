"""What a monocular study is and what one run of it produced.

The scenario definition (:class:`MonocularScenario`, read from TOML by
:mod:`lightcurve.scenarios.monocular`) with its truth, pixel set-up and success criteria, and
the run record (:class:`Study`) that :func:`lightcurve.studies.monocular.run_study` returns and
:mod:`lightcurve.studies.monocular_summary` reads. All importable from
:mod:`lightcurve.studies.monocular`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from filters.navigation.camera import PinholeCamera
from filters.navigation.monocular import (
    FilterHistory,
    InertiaForm,
    reference_frame_truth,
)
from lightcurve.io.scenario_files import ScenarioError

L_NAMES = ("Lxx", "Lyy", "Lxy", "Lxz", "Lyz")


@dataclass(frozen=True)
class Truth:
    """Simulated motion: inertia ``J`` (body frame), ``q0`` (camera → body), ``ω0`` (rad/s)."""

    inertia: np.ndarray
    q0: np.ndarray
    omega0: np.ndarray
    duration: float
    step: float

    @property
    def times(self) -> np.ndarray:
        """Frame times ``0, step, …, duration`` (s)."""
        return np.arange(0.0, self.duration + 0.5 * self.step, self.step)


@dataclass(frozen=True)
class PixelSetup:
    """Camera, target and image-processing settings of the ``pixels`` measurement mode."""

    camera: PinholeCamera
    shape: str
    radius_m: float
    range_m: float
    pixel_sigma: float
    outlier_fraction: float
    threshold_px: float
    refine_iterations: int
    linking: str
    min_matches: int


@dataclass(frozen=True)
class Criteria:
    """Success thresholds for the nutating-body scenario (A) and the settling window."""

    attitude_deg: float = 0.5
    rate_fraction: float = 0.02
    inertia: float = 0.02
    settle_fraction: float = 0.25


@dataclass(frozen=True)
class MonocularScenario:
    """A parsed scenario file (SI units inside)."""

    path: Path
    name: str
    truth: Truth | None
    mode: str
    sigma: float | None
    pixels: PixelSetup | None
    form: InertiaForm
    x0: np.ndarray
    p0: np.ndarray
    q: np.ndarray
    r: np.ndarray
    criteria: Criteria = field(default_factory=Criteria)
    max_order: int = 6
    rtol: float = 1e-9


def form_truth(form: InertiaForm, inertia: np.ndarray, q0: np.ndarray) -> np.ndarray:
    """Truth inertia parameters in the filter's frame (the first camera frame)."""
    states = np.concatenate([q0, np.zeros(3)])[None]
    _, _, j_ref = reference_frame_truth(inertia, q0, states)
    try:
        return np.asarray(form.from_inertia(j_ref), dtype=float)
    except ValueError as exc:
        message = (
            f"inertia form {form.name!r} cannot represent the truth in the first camera frame "
            f"({exc}); use form 'L'"
        )
        raise ScenarioError(message) from None


@dataclass
class Study:
    """Everything one scenario run produced (run 0 is the reported run)."""

    scenario: MonocularScenario
    times: np.ndarray
    measurements: np.ndarray  # (K, runs, 4)
    history: FilterHistory
    truth_q: np.ndarray | None = None  # (K, 4)
    truth_omega: np.ndarray | None = None  # (K, 3)
    truth_p: np.ndarray | None = None  # (m,)
    measurement_info: dict[str, Any] = field(default_factory=dict)
    seconds: dict[str, float] = field(default_factory=dict)
    external: bool = False
