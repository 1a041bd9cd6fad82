"""Shared fixtures: the repository's exemplar fixtures, the command-line binary, and an analysis
cache of the session's own (so the tests neither read nor fill the user's)."""

import os
import subprocess
from pathlib import Path

import pytest

PYTHON_DIR = Path(__file__).resolve().parents[1]
FIXTURES = PYTHON_DIR.parent / "tests" / "fixtures"


@pytest.fixture(scope="session", autouse=True)
def analysis_cache(tmp_path_factory):
    """The session's analysis cache, shared by the package and the command line it is compared
    with (the library reads SOLIDSYNTH_CACHE_DIR when a Solid is built)."""
    directory = tmp_path_factory.mktemp("analysis-cache")
    previous = os.environ.get("SOLIDSYNTH_CACHE_DIR")
    os.environ["SOLIDSYNTH_CACHE_DIR"] = str(directory)
    yield directory
    if previous is None:
        os.environ.pop("SOLIDSYNTH_CACHE_DIR", None)
    else:
        os.environ["SOLIDSYNTH_CACHE_DIR"] = previous


@pytest.fixture(scope="session")
def fixture_path():
    """The path of a fixture image of the repository (tests/fixtures)."""

    def path(name: str) -> Path:
        p = FIXTURES / name
        assert p.exists(), p
        return p

    return path


@pytest.fixture(scope="session")
def cli():
    """Run the `solidsynth` binary (SOLIDSYNTH_BIN, else ../target/debug/solidsynth); skipped
    where it is absent, except in CI (CI set), where its absence is a failure."""
    binary = Path(os.environ.get("SOLIDSYNTH_BIN", PYTHON_DIR / ".." / "target/debug/solidsynth"))
    if not binary.exists():
        message = f"the solidsynth binary is not at {binary} (build it, or set SOLIDSYNTH_BIN)"
        if os.environ.get("CI"):
            pytest.fail(message)
        pytest.skip(message)

    def run(*args, ok: bool = True) -> subprocess.CompletedProcess:
        env = dict(os.environ, SOLIDSYNTH_LOG="warn")
        done = subprocess.run(
            [str(binary), *map(str, args)], capture_output=True, text=True, env=env
        )
        if ok:
            assert done.returncode == 0, done.stderr
        return done

    return run


@pytest.fixture(scope="session")
def read_nrrd():
    """(sizes C X Y Z, data bytes) of a raw NRRD file as the command line writes it."""

    def read(path: Path):
        raw = Path(path).read_bytes()
        end = raw.index(b"\n\n")
        header = raw[:end].decode().splitlines()
        assert header[0].startswith("NRRD")
        fields = dict(line.split(": ", 1) for line in header[1:] if not line.startswith("#"))
        assert fields["type"] == "uint8" and fields["encoding"] == "raw", fields
        sizes = tuple(int(n) for n in fields["sizes"].split())
        return sizes, raw[end + 2 :]

    return read


@pytest.fixture(scope="session")
def cells(fixture_path):
    """A small, quickly analysed solid: tests/fixtures/cells32.png, tiling, no balancing, seed
    2, CPU backend (the command line's flags: --periodic --balance-rounds 0 --seed 2)."""
    import solidsynth

    return solidsynth.Solid(
        fixture_path("cells32.png"), seed=2, periodic=True, balance_rounds=0, backend="cpu"
    )
