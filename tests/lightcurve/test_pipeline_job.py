"""`invert_file` takes one frozen job object and the inversion's options."""

from __future__ import annotations

import dataclasses
import pickle

import numpy as np
import pytest

from lightcurve.inversion import InversionOptions
from lightcurve.pipeline import InvertJob, check_request


def test_the_job_is_frozen_plain_data():
    job = InvertJob(method="mmae", shape_names=["box", "cube"], q0=np.array([0.0, 0.0, 0.0, 1.0]))
    assert job.shape_names == ("box", "cube")
    assert job.q0 == (0.0, 0.0, 0.0, 1.0) and all(type(v) is float for v in job.q0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        job.seed = 1  # type: ignore[misc]
    assert pickle.loads(pickle.dumps(job)) == job  # ships to worker processes
    assert hash(job) == hash(InvertJob("mmae", ("box", "cube"), q0=(0.0, 0.0, 0.0, 1.0)))


def test_the_request_is_checked_with_the_library_rules():
    check_request(InvertJob("ukf", ("box",)), InversionOptions())
    with pytest.raises(ValueError, match="exactly one shape"):
        check_request(InvertJob("ukf", ("box", "cube")))
    with pytest.raises(ValueError, match="init='none' needs q0"):
        check_request(InvertJob("ukf", ("box",)), InversionOptions(init="none"))
    with pytest.raises(ValueError, match="need modes=True"):
        check_request(InvertJob("mmae"), InversionOptions(mode_weak_sigma_deg=2.0))
    check_request(InvertJob("mmae", modes=True), InversionOptions(mode_weak_sigma_deg=2.0))
    with pytest.raises(ValueError, match="particles must be positive"):
        check_request(InvertJob("pf", particles=0))
