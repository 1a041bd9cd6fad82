"""A Solid gives the command line's bytes, and the same voxels whichever part asks for them."""

import numpy as np
import pytest

import solidsynth

# The command line's flags of the `cells` fixture's solid.
CELLS_FLAGS = ["--periodic", "--balance-rounds", "0", "--seed", "2", "--backend", "cpu"]


@pytest.mark.parametrize(
    "exemplar, flags, options, lo, hi",
    [
        # A fixture image, tiling, without balancing.
        (
            "cells32.png",
            ["--periodic", "--balance-rounds", "0"],
            dict(periodic=True, balance_rounds=0),
            (-5, 3, -9),
            (11, 12, 4),
        ),
        # A fixture image with the command line's defaults (mirrored borders, balancing).
        ("marble32.png", [], {}, (0, 0, 0), (12, 10, 8)),
        # The fitted colour rule (its colours read neighbours around the box).
        ("marble32.png", ["--color", "fitted"], dict(color="fitted"), (-3, 2, 1), (9, 11, 7)),
        # The built-in exemplar (paper frame, feature masks, balancing).
        (None, [], {}, (-5, 3, -9), (11, 12, 4)),
    ],
)
def test_a_region_is_the_command_lines_nrrd(
    cli, read_nrrd, fixture_path, tmp_path, exemplar, flags, options, lo, hi
):
    path = fixture_path(exemplar) if exemplar else None
    out = tmp_path / "region.nrrd"
    box = ",".join(str(c) for c in (*lo, *hi))
    cli("region", *([path] if path else []), "--box", box, "--seed", "6", "--backend", "cpu",
        *flags, "-o", out)
    sizes, data = read_nrrd(out)

    array = solidsynth.Solid(path, seed=6, backend="cpu", **options).region(lo, hi)

    c, x, y, z = sizes
    assert array.shape == (z, y, x, c)
    assert array.dtype == np.uint8
    assert array.flags.c_contiguous
    assert array.tobytes() == data


def test_a_box_holds_the_same_voxels_as_a_larger_box(cells):
    big = cells.region((-8, 0, 4), (16, 20, 16))
    small = cells.region([-3, 5, 7], np.array([9, 13, 12]))
    # Array index [z - 4, y - 0, x + 8] of the big box.
    np.testing.assert_array_equal(small, big[3:8, 5:13, 5:17])


def test_an_array_exemplar_is_the_files(fixture_path):
    image = pytest.importorskip("PIL.Image")
    path = fixture_path("cells32.png")
    pixels = np.asarray(image.open(path))
    options = dict(seed=3, periodic=True, balance_rounds=0, backend="cpu")
    from_file = solidsynth.Solid(path, **options).region((0, 0, 0), (8, 8, 8))
    from_array = solidsynth.Solid(pixels, **options).region((0, 0, 0), (8, 8, 8))
    np.testing.assert_array_equal(from_array, from_file)
    # Any strides: a Fortran-ordered copy is the same image.
    fortran = solidsynth.Solid(np.asfortranarray(pixels), **options)
    np.testing.assert_array_equal(fortran.region((0, 0, 0), (8, 8, 8)), from_file)


@pytest.mark.parametrize("shape", [(24, 20), (24, 20, 1), (24, 20, 3), (24, 20, 4)])
def test_array_exemplars_of_every_channel_count(shape):
    rng = np.random.default_rng(1)
    pixels = rng.integers(0, 256, size=shape, dtype=np.uint8)
    solid = solidsynth.Solid(pixels, periodic=True, balance_rounds=0, backend="cpu")
    channels = 1 if len(shape) == 2 else shape[2]
    assert solid.channels == channels
    assert solid.region((0, 0, 0), (4, 5, 6)).shape == (6, 5, 4, channels)


def test_three_exemplars(fixture_path):
    solid = solidsynth.Solid(
        fixture_path("cells32.png"),
        ey=fixture_path("marble32.png"),
        ez=fixture_path("cells32.png"),
        balance_rounds=0,
        backend="cpu",
    )
    assert solid.region((0, 0, 0), (4, 4, 4)).shape[:3] == (4, 4, 4)


def test_an_axis_aligned_cut_is_a_slice_of_the_solid(cells):
    # Normal +z, rows along +y: pixel (column i, row j) samples voxel
    # (floor(16 + i + 0.5 - 16), floor(16 + j + 0.5 - 16), floor(3.5)) = (i, j, 3).
    cut = cells.cut((16.0, 16.0, 3.5), (0, 0, 1), size=32)
    assert cut.shape == (32, 32, cells.channels)
    np.testing.assert_array_equal(cut, cells.region((0, 0, 3), (32, 32, 4))[0])


def test_an_oblique_cut_is_deterministic(cells):
    a = cells.cut((1000.0, -500.0, 77.0), (1, 2, 3), size=48, spacing=0.75)
    b = cells.cut([1000, -500, 77], [1.0, 2.0, 3.0], up=None, size=48, spacing=0.75)
    assert a.shape == (48, 48, cells.channels)
    np.testing.assert_array_equal(a, b)


def test_a_cut_is_the_command_lines_png(cli, fixture_path, tmp_path, cells):
    image = pytest.importorskip("PIL.Image")
    out = tmp_path / "cut.png"
    cli("cut", fixture_path("cells32.png"), *CELLS_FLAGS, "--origin", "3,-7,11",
        "--normal", "1,2,3", "--size", "40", "-o", out)
    cut = cells.cut((3, -7, 11), (1, 2, 3), size=40)
    png = np.asarray(image.open(out).convert("RGBA"))
    rgb = cut if cut.shape[2] >= 3 else np.repeat(cut, 3, axis=2)
    np.testing.assert_array_equal(png[..., :3], rgb[..., :3])


def test_a_tileable_solid(cells):
    volume = cells.tileable(32)
    assert volume.shape == (32, 32, 32, cells.channels)
    with pytest.raises(ValueError, match="multiple of 32"):
        cells.tileable(40)


def test_an_analysis_file_gives_the_same_solid(cells, tmp_path):
    path = tmp_path / "cells.ssa"
    cells.save_analysis(path)
    expected = cells.region((-4, 0, 2), (8, 6, 9))

    loaded = solidsynth.Solid.load(path, **cells.options)
    assert loaded.options == cells.options
    np.testing.assert_array_equal(loaded.region((-4, 0, 2), (8, 6, 9)), expected)
    # An .ssa file as the exemplar argument, as the command line's INPUT.
    as_input = solidsynth.Solid(path, seed=2, backend="cpu")
    np.testing.assert_array_equal(as_input.region((-4, 0, 2), (8, 6, 9)), expected)
    # Analysis settings with an analysis file are refused.
    with pytest.raises(ValueError, match="an .ssa file already holds them"):
        solidsynth.Solid(path, frame="cyclic", backend="cpu")


def test_options_and_description(cells):
    assert cells.options == dict(
        seed=2,
        jitter=1.0,
        backend="cpu",
        adapter=None,
        candidates="3d",
        passes="2",
        color="average",
        coarse_cache=None,
        max_group=None,
    )
    assert cells.backend.startswith("cpu")
    assert "seed=2" in repr(cells)
    assert isinstance(cells.channels, int)


@pytest.mark.parametrize("x0", [67108864, 268435447, -268435456])
def test_boxes_at_the_far_edges_of_the_coordinate_range_are_the_command_lines(
    cli, read_nrrd, tmp_path, x0
):
    # Far from the origin the jitter field's fixed-point positions leave i32 and wrap; this
    # build (the tests' dev profile, overflow checks on) must give the release binary's bytes.
    out = tmp_path / "far.nrrd"
    box = f"{x0},0,0,{x0 + 8},8,8"
    cli("region", "--box", box, "--seed", "1", "--backend", "cpu", "-o", out)
    _, data = read_nrrd(out)
    array = solidsynth.Solid(None, seed=1, backend="cpu").region((x0, 0, 0), (x0 + 8, 8, 8))
    assert array.tobytes() == data
