"""`lightcurve plot` given the batch folder instead of one input's folder says which to pass."""

import json

import pytest

from lightcurve.plots import load_result


def test_a_batch_folder_names_the_result_folders_inside(tmp_path):
    for stem in ("b", "a"):
        (tmp_path / stem).mkdir()
        (tmp_path / stem / "summary.json").write_text(json.dumps({"status": "ok"}))
    with pytest.raises(FileNotFoundError) as error:
        load_result(tmp_path)
    message = str(error.value)
    assert "whole batch" in message
    assert message.endswith(f"{tmp_path / 'a'}, {tmp_path / 'b'}")


def test_a_folder_without_results_is_not_an_inversion_result(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"no summary\.json"):
        load_result(tmp_path)
