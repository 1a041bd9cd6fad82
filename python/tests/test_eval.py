"""`solidsynth.eval` is `solidsynth eval --json`."""

import json

import numpy as np
import pytest

import solidsynth

CELLS_FLAGS = ["--periodic", "--balance-rounds", "0", "--seed", "2", "--backend", "cpu"]


def test_eval_is_the_command_lines_json(cli, cells, fixture_path, tmp_path):
    exemplar = fixture_path("cells32.png")
    volume_path = tmp_path / "volume.nrrd"
    cli("region", exemplar, *CELLS_FLAGS, "--box", "0,0,0,20,20,20", "-o", volume_path)
    expected = json.loads(cli("eval", exemplar, volume_path, "--json").stdout)

    assert solidsynth.eval(exemplar, volume_path) == expected
    # The same volume as an array.
    volume = cells.region((0, 0, 0), (20, 20, 20))
    assert solidsynth.eval(exemplar, volume) == expected


def test_eval_document(cells, fixture_path):
    volume = cells.region((0, 0, 0), (16, 16, 16))
    report = solidsynth.eval(fixture_path("cells32.png"), volume, slices=2, seed=3)
    assert report["schema"] == 1
    assert report["slices_per_axis"] == 2
    assert len(report["per_axis"]) == 3
    for key in ("worst_axis", "floor", "worst_ratio", "multiscale"):
        assert key in report
    # A gray (Z, Y, X) volume is one channel.
    gray = np.ascontiguousarray(volume[..., 0])
    assert solidsynth.eval(fixture_path("cells32.png"), gray)["schema"] == 1


def test_eval_refuses_bad_volumes(fixture_path):
    exemplar = fixture_path("cells32.png")
    with pytest.raises(ValueError, match="^invalid volume: is 4x4x4; each side must be at least"):
        solidsynth.eval(exemplar, np.zeros((4, 4, 4, 3), dtype=np.uint8))
    with pytest.raises(ValueError, match="^invalid volume: has dtype float32"):
        solidsynth.eval(exemplar, np.zeros((16, 16, 16), dtype=np.float32))
    with pytest.raises(ValueError, match="^invalid volume: has 5 channels"):
        solidsynth.eval(exemplar, np.zeros((16, 16, 16, 5), dtype=np.uint8))
    with pytest.raises(ValueError, match="^invalid --slices 0"):
        solidsynth.eval(exemplar, np.zeros((16, 16, 16), dtype=np.uint8), slices=0)
