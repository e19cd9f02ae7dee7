"""Numbers the command line prints: epochs without float round-off, matrices without -0 noise."""

import numpy as np

from lightcurve.commands.shapes import _matrix
from lightcurve.io.observations import iso_epochs


def test_epochs_on_a_whole_second_grid_print_as_milliseconds():
    mjd = 60379.2 + np.arange(3600) / 86400.0  # an hour at 1 s, as `lightcurve geometry` writes
    epochs = iso_epochs(mjd)
    assert all(text.endswith(".000Z") for text in epochs)
    assert epochs[7] == "2024-03-10T04:48:07.000Z"


def test_epochs_measured_to_the_microsecond_keep_microseconds():
    seconds = np.array([10.373458, 20.5, 31.000250])
    epochs = iso_epochs(58860.0 + seconds / 86400.0)
    assert [text[-7:] for text in epochs] == ["373458Z", "500000Z", "000250Z"]


def test_round_off_in_a_printed_matrix_is_zero():
    inertia = np.array(
        [[5902.73, -2.89e-17, 0.0], [-2.89e-17, 3841.82, 5.3e-15], [0, 5.3e-15, 5185.95]]
    )
    text = _matrix(inertia)
    assert "e-" not in text and "-0" not in text
    assert text.split()[0] == "5902.73" and text.split()[1] == "0"
    assert "1e-06" in _matrix(np.diag([1.0, 1e-6, 2.0]))  # small but real: kept
