"""The inversion's options are checked per method, once, by the library; the CLI reports
the library's verdict in one line before it reads any input."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from lightcurve.cli import main
from lightcurve.inversion import (
    METHOD_OPTIONS,
    METHODS,
    InversionOptions,
    validate_request,
)

SAMPLE = Path(__file__).resolve().parents[3] / "data" / "observations" / "box_wing_tumbling.csv"
Q0 = [0.2, -0.1, 0.3, 0.927]


@pytest.mark.parametrize(
    ("method", "option", "value"),
    [
        ("pf", "estimate_offset", True),
        ("pf", "init", "none"),
        ("pf", "gate_probability", 0.0),
        ("ukf", "moves", 2),
        ("ukf", "probability_floor", 0.01),
        ("mmae", "likelihood", "student"),
    ],
)
def test_an_option_the_method_ignores_is_an_error(method, option, value):
    assert option not in METHOD_OPTIONS[method]
    with pytest.raises(ValueError, match=f"method '{method}' does not use the option.*{option}"):
        validate_request(method, q0=Q0, **{option: value})


def test_every_option_is_read_by_some_method_and_accepted_there():
    fields = {f.name for f in InversionOptions.__dataclass_fields__.values()}
    modes_only = {"mode_offset_sigma_deg", "mode_consistency_level", "mode_weak_sigma_deg"}
    assert set().union(*METHOD_OPTIONS.values()) | modes_only == fields
    assert validate_request("pf", moves=2, likelihood="student").moves == 2
    assert validate_request("mmae", probability_floor=0.01, estimate_offset=True).estimate_offset
    with pytest.raises(ValueError, match="need modes=True"):
        validate_request("ukf", mode_offset_sigma_deg=5.0)
    assert validate_request("ukf", modes=True, mode_offset_sigma_deg=5.0).mode_offset_sigma_deg == 5


def test_request_errors_name_what_is_wrong():
    with pytest.raises(ValueError, match="method must be one of"):
        validate_request("ekf")
    with pytest.raises(ValueError, match="unknown inversion option"):
        validate_request("ukf", max_epochs=60)
    with pytest.raises(ValueError, match="init='none' needs q0"):
        validate_request("mmae", init="none")
    with pytest.raises(ValueError, match="exactly one shape, got 2"):
        validate_request("ukf", n_shapes=2)
    with pytest.raises(ValueError, match="particles must be positive"):
        validate_request("pf", particles=0)
    with pytest.raises(ValueError, match="omega_max must be positive"):
        validate_request("pf", omega_max=math.nan)
    with pytest.raises(ValueError, match="pf_rate_scales must be in"):
        validate_request("pf", pf_rate_scales=(1.0, 0.0))
    with pytest.raises(ValueError, match="q0 must be 4 finite numbers"):
        validate_request("ukf", q0=[0.0, 0.0, 1.0])
    # The filters may start at q0 alone (zero rates with their 1σ).
    assert validate_request("ukf", init="none", q0=Q0).init == "none"
    assert set(METHODS) == set(METHOD_OPTIONS)


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--method", "pf", "--init", "none", "--q0", "0,0,0,1"], "'pf' does not use the option"),
        (["--method", "ukf", "--init", "none"], "init='none' needs q0"),
        (["--method", "ukf", "--shapes", "box,box_wing"], "exactly one shape, got 2"),
        (["--method", "pf", "--particles", "0"], "particles must be positive"),
    ],
)
def test_cli_reports_the_library_check_in_one_line_before_reading_inputs(
    tmp_path, capsys, extra, message
):
    out = tmp_path / "result"
    assert main(["invert", str(SAMPLE), *extra, "--no-progress", "--out", str(out)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], lines
    assert not out.exists()


def test_request_check_accepts_the_inversion_defaults():
    """``validate_request`` checks what ``invert`` will run: it takes ``invert``'s request
    parameters with ``invert``'s defaults or None (standing for them), and those defaults
    pass the check."""
    import inspect

    from lightcurve.inversion import invert

    run = inspect.signature(invert).parameters
    check = inspect.signature(validate_request).parameters
    shared = (set(run) & set(check)) - {"options", "option_overrides", "method"}
    assert {"attitude_sigma_deg", "omega_sigma", "omega_max", "particles", "q0"} <= shared
    for name in shared:
        assert check[name].default in (None, run[name].default), name
    for method in METHODS:
        validate_request(method, n_shapes=1, **{name: run[name].default for name in shared})
