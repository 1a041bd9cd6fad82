"""`solidsynth.dask`: a Dask array of a solid is the solid, whichever worker computes a block."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("dask.array")

import solidsynth  # noqa: E402
import solidsynth.dask  # noqa: E402

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "dask_local.py"


def test_a_dask_array_is_the_region(cells, tmp_path):
    array = solidsynth.dask.region(
        cells, (20, 24, 28), (8, 16, 12), origin=(-5, 3, 7), ssa_dir=tmp_path
    )
    assert array.shape == (20, 24, 28, cells.channels)
    assert array.dtype == np.uint8
    # Threads of this process: several blocks at once on one (cached) solid.
    computed = array.compute(scheduler="threads")
    whole = cells.region((-5, 3, 7), (-5 + 28, 3 + 24, 7 + 20))
    np.testing.assert_array_equal(computed, whole)


@pytest.mark.parametrize(
    "shape, chunks, message",
    [
        ("888", 4, r"shape: expected three positive sizes \(Z, Y, X\), got '888'"),
        ((8.9, 8, 8), 4, r"shape: expected three positive sizes"),
        (8, 4, r"shape: expected three positive sizes"),
        ((8, 8, 0), 4, r"shape: expected three positive sizes"),
        ((8, 8, 8), 0, r"chunks 0: "),
        ((10**6,) * 3, 128, r"blocks; at most 1000000"),
        ((2**28,) * 3, 1, r"blocks; at most 1000000"),
    ],
)
def test_bad_shapes_and_chunks_are_refused_before_the_graph(cells, shape, chunks, message):
    with pytest.raises(ValueError, match=message):
        solidsynth.dask.region(cells, shape, chunks)
    # NumPy integers are integers.
    assert solidsynth.dask.region(cells, np.array([8, 8, 8]), 4).shape[:3] == (8, 8, 8)


def test_sources(cells, fixture_path, tmp_path):
    options = dict(seed=2, periodic=True, balance_rounds=0, backend="cpu")
    expected = cells.region((0, 0, 0), (8, 8, 8))
    # An image, analysed in this process and written for the workers.
    from_image = solidsynth.dask.region(
        fixture_path("cells32.png"), (8, 8, 8), 4, ssa_dir=tmp_path, **options
    )
    np.testing.assert_array_equal(from_image.compute(scheduler="sync"), expected)
    # An analysis file.
    ssa = tmp_path / "cells.ssa"
    cells.save_analysis(ssa)
    from_file = solidsynth.dask.region(ssa, (8, 8, 8), 4, seed=2, backend="cpu")
    np.testing.assert_array_equal(from_file.compute(scheduler="sync"), expected)
    with pytest.raises(TypeError, match="give none"):
        solidsynth.dask.region(cells, (8, 8, 8), 4, seed=3)


def test_the_local_cluster_example(fixture_path):
    pytest.importorskip("distributed")
    pytest.importorskip("zarr")
    spec = importlib.util.spec_from_file_location("dask_local", EXAMPLE)
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    assert example.run(
        size=32,
        chunk=16,
        exemplar=str(fixture_path("cells32.png")),
        seed=2,
        periodic=True,
        balance_rounds=0,
        backend="cpu",
    )
