"""Bad input is refused before any work, with a message that names it (the command line's where
it has the same input)."""

import numpy as np
import pytest

import solidsynth

CPU = dict(backend="cpu")


@pytest.mark.parametrize(
    "pixels, message",
    [
        (np.zeros((32, 32, 3), dtype=np.float32), "has dtype float32; expected uint8"),
        (np.zeros((32, 32), dtype=np.int64), "has dtype int64; expected uint8"),
        (np.zeros((32, 32, 5), dtype=np.uint8), "has 5 channels; expected 1"),
        (np.zeros((32, 32, 2), dtype=np.uint8), "has 2 channels"),
        (np.zeros((0, 0), dtype=np.uint8), r"is empty \(shape \(0, 0\)\)"),
        (np.zeros((0, 32, 3), dtype=np.uint8), "is empty"),
        (np.zeros(32, dtype=np.uint8), r"has shape \(32,\); expected \(H, W\) or \(H, W, C\)"),
        (np.zeros((2, 32, 32, 3), dtype=np.uint8), "expected \\(H, W\\) or \\(H, W, C\\)"),
        (np.zeros((8, 8), dtype=np.uint8), "each side must be at least 16 pixels"),
    ],
)
def test_bad_exemplar_arrays(pixels, message):
    with pytest.raises(ValueError, match=message) as refused:
        solidsynth.Solid(pixels, **CPU)
    assert str(refused.value).startswith("invalid exemplar")


def test_a_bad_ey_array_is_named_as_the_flag():
    good = np.zeros((32, 32, 3), dtype=np.uint8)
    with pytest.raises(ValueError, match="^invalid --ey: has dtype float64"):
        solidsynth.Solid(good, ey=good.astype(np.float64), ez=good, **CPU)


def test_exemplars_come_as_the_command_line_takes_them(fixture_path):
    path = fixture_path("cells32.png")
    with pytest.raises(ValueError, match="--ey: needs --ez too"):
        solidsynth.Solid(path, ey=path, **CPU)
    with pytest.raises(ValueError, match="--ey: needs the x exemplar INPUT too"):
        solidsynth.Solid(ey=path, ez=path, **CPU)
    with pytest.raises(TypeError, match="expected a path or a NumPy uint8 array"):
        solidsynth.Solid(42, **CPU)


def test_a_missing_file_is_an_os_error(tmp_path):
    missing = tmp_path / "missing.png"
    with pytest.raises(FileNotFoundError, match="missing.png"):
        solidsynth.Solid(missing, **CPU)
    with pytest.raises(FileNotFoundError):
        solidsynth.Solid.load(tmp_path / "missing.ssa", **CPU)


def test_a_damaged_analysis_file_is_refused(tmp_path):
    path = tmp_path / "damaged.ssa"
    path.write_bytes(b"SOLIDSSA" + bytes(40))
    with pytest.raises(ValueError, match="damaged.ssa"):
        solidsynth.Solid.load(path, **CPU)


@pytest.mark.parametrize(
    "options, message",
    [
        (dict(backend="vulkan"), "invalid --backend vulkan: expected auto, cpu or gpu"),
        (dict(candidates="4d"), "invalid --candidates 4d"),
        (dict(passes="2,2"), "invalid --passes 2,2"),
        (dict(passes=9), "invalid --passes 9"),
        (dict(color="purple"), "invalid --color purple"),
        (dict(jitter=-1.0), "invalid --jitter -1"),
        (dict(coarse_cache=100), "invalid --coarse-cache 100"),
        (dict(max_group=2), "invalid --max-group 2"),
        (dict(frame="diagonal"), "invalid --frame diagonal"),
        (dict(seed=-1), r"invalid --seed -1: must be 0..=18446744073709551615"),
        (dict(seed=2**64), "invalid --seed 18446744073709551616"),
        (dict(coarse_cache=-64), "invalid --coarse-cache -64: must be a multiple of 64 in"),
        (dict(max_group=2**40), r"invalid --max-group 1099511627776: must be a multiple of 4 \(whole bricks\) in 4..=512"),
        (dict(seed=2**128), "invalid --seed 340282366920938463463374607431768211456: must be 0"),
        (dict(balance_rounds=-1), "invalid --balance-rounds -1: must be 0..="),
        (dict(passes=-1), "invalid --passes -1"),
        (dict(passes=2**40), "invalid --passes 1099511627776"),
        (dict(passes=[2, 2, -1, 1]), r"invalid --passes 2,2,-1,1"),
        (dict(cache=""), "invalid cache '': is an empty path"),
    ],
)
def test_bad_settings_name_their_flag(options, message):
    with pytest.raises(ValueError, match=message):
        solidsynth.Solid(**{**CPU, **options})


@pytest.mark.parametrize(
    "lo, hi, message",
    [
        ((0, 0, 0), (-4, 4, 4), "X1 must be greater than X0"),
        ((0, 0, 0), (4, 4, 0), "Z1 must be greater than Z0"),
        ((0, 5, 0), (4, 5, 4), "Y1 must be greater than Y0"),
        ((0, 0, 0), (4000, 4, 4), "each side must be at most 2048 voxels"),
        ((0, 0, -(1 << 29)), (4, 4, 4), "coordinates must lie within"),
    ],
)
def test_bad_boxes(cells, lo, hi, message):
    with pytest.raises(ValueError, match=message) as refused:
        cells.region(lo, hi)
    assert str(refused.value).startswith("invalid --box ")


@pytest.mark.parametrize(
    "options, message",
    [
        (dict(passes=2.5), "passes: expected an int, a string"),
        (dict(cache=None), r"cache: expected True, False or a directory"),
        (dict(seed="7"), "expected an int, got str"),
        (dict(seed=True), "expected an int, got bool"),
    ],
)
def test_arguments_of_the_wrong_type_say_what_they_take(options, message):
    with pytest.raises(TypeError, match=message):
        solidsynth.Solid(**{**CPU, **options})


def test_integers_past_every_type_are_value_errors_naming_their_argument(cells, tmp_path):
    with pytest.raises(ValueError, match=r"^invalid --box 0,0,0,9223372036854775808,8,8: "):
        cells.region((0, 0, 0), (2**63, 8, 8))
    with pytest.raises(ValueError, match=r"^invalid --size 9223372036854775808: must be 8..=2048"):
        cells.tileable(2**63)
    with pytest.raises(ValueError, match=r"^invalid --size 1180591620717411303424: must be 1..="):
        cells.cut((0, 0, 0), (0, 0, 1), size=2**70)
    volume = np.zeros((16, 16, 16, 3), dtype=np.uint8)
    exemplar = np.zeros((32, 32, 3), dtype=np.uint8)
    with pytest.raises(ValueError, match=r"^invalid --seed -1: must be 0..="):
        solidsynth.eval(exemplar, volume, seed=-1)
    with pytest.raises(ValueError, match=r"^invalid --slices 1180591620717411303424: must be 1..=64"):
        solidsynth.eval(exemplar, volume, slices=2**70)
    with pytest.raises(ValueError, match=r"^invalid -o '': is an empty path"):
        cells.save_analysis("")


def test_numpy_values_are_taken_as_python_ones(cells, fixture_path):
    import inspect

    counts = solidsynth.Solid(
        fixture_path("cells32.png"), **CPU, balance_rounds=0,
        passes=np.array([2, 2, 2, 1]), cache=np.True_,
    )
    assert counts.options["passes"] == "2,2,2,1"
    with pytest.raises(TypeError, match="passes: expected an int"):
        solidsynth.Solid(**CPU, passes=b"22")
    assert "self" not in inspect.signature(cells.cut).parameters


def test_signatures_show_their_defaults():
    import inspect

    parameters = inspect.signature(solidsynth.Solid).parameters
    assert parameters["backend"].default == "auto"
    assert parameters["passes"].default == 2
    assert parameters["cache"].default is True
    assert inspect.signature(solidsynth.Solid.load).parameters["color"].default == "average"
    assert inspect.signature(solidsynth.eval).parameters["slices"].default == 3


def test_bad_sizes(cells):
    with pytest.raises(ValueError, match=r"^invalid --size -32: must be 8..=2048"):
        cells.tileable(-32)
    with pytest.raises(ValueError, match=r"^invalid --size -1: must be 1..=4096"):
        cells.cut((0, 0, 0), (0, 0, 1), size=-1)
    with pytest.raises(ValueError, match="--normal"):
        cells.cut((0, 0, 0), (0, 0, 0))
    with pytest.raises(ValueError, match="--spacing"):
        cells.cut((0, 0, 0), (0, 0, 1), spacing=0.0)


def test_messages_are_the_command_lines(cli, cells, tmp_path):
    done = cli("region", "--box", "0,0,0,-4,4,4", "-o", tmp_path / "x.nrrd", ok=False)
    assert done.returncode == 2
    with pytest.raises(ValueError) as refused:
        cells.region((0, 0, 0), (-4, 4, 4))
    assert done.stderr.strip() == f"error: {refused.value}"


def test_errors_are_exception_classes():
    assert issubclass(solidsynth.Error, Exception)
    assert solidsynth.Error.__module__ == "solidsynth"


def test_a_cache_that_cannot_be_written_is_a_warning(fixture_path, tmp_path):
    not_a_dir = tmp_path / "file"
    not_a_dir.write_bytes(b"")
    with pytest.warns(UserWarning, match=r"could not cache the analysis: .*is not a directory"):
        solid = solidsynth.Solid(
            fixture_path("cells32.png"), **CPU, balance_rounds=0, cache=not_a_dir
        )
    assert solid.region((0, 0, 0), (4, 4, 4)).shape == (4, 4, 4, 3)
