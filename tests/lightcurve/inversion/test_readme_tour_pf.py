"""The README tour's particle-filter step: three candidate shapes on the sample CCD light
curve of a tumbling box, from a uniform attitude prior. It picks the box and ends within 3°
of the file's truth modulo the box's symmetry group (0.66° on this machine, 13–25 s of CPU;
before the three-shape inertia fix 84° off)."""

import math
import re
import shlex
from pathlib import Path

import numpy as np
import pytest

from lightcurve.cli import main
from lightcurve.plots import load_result

ROOT = Path(__file__).resolve().parents[3]


def tour_command(marker: str) -> list[str]:
    """The words of the README tour's line that contains ``marker`` (comment dropped)."""
    text = (ROOT / "README.md").read_text()
    tour = re.search(r"## A short tour.*?```bash\n(.+?)\n```", text, re.S)
    assert tour, "README.md has no tour"
    lines = [line for line in tour.group(1).splitlines() if marker in line]
    assert len(lines) == 1, f"the tour has {len(lines)} lines with {marker!r}"
    return shlex.split(lines[0], comments=True)


def test_the_tour_particle_filter_finds_the_box_within_three_degrees(tmp_path):
    words = tour_command("--method pf")
    assert words[:2] == ["lightcurve", "invert"]
    # Inputs from the checkout, outputs in a temporary folder.
    args = [str(ROOT / w) if w.startswith("data/") else w for w in words[1:]]
    out = args.index("--out") + 1
    args[out] = str(tmp_path / args[out])
    assert main(["-q", *args]) == 0
    result = load_result(Path(args[out]) / "box_tumbling_ccd")
    summary = result.summary
    assert summary["shape"] == "box" and summary["shape_probabilities"]["box"] >= 0.9
    assert not summary["none_fits"], summary["notes"]
    truth = result.observations.truth[-1]
    error = result.symmetry.attitude_error(np.asarray(summary["quaternion"]), truth[:4])
    assert math.degrees(float(error)) < 3.0, summary["notes"]
    # the PF's model error: its residuals beyond the measurement errors (a CCD file whose
    # object is exactly the box: near zero)
    rms, noise = (
        summary["residual_rms_mag"],
        float(np.sqrt(np.mean(result.observations.magnitude_errors**2))),
    )
    assert summary["model_error_mag"] == pytest.approx(
        math.sqrt(max(rms**2 - noise**2, 0.0)), abs=0.01
    )
    assert summary["model_error_mag"] < 0.03
