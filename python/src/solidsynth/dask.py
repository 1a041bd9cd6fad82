"""Solids as Dask arrays: each block synthesized on whichever worker runs it.

A block's voxels depend only on their coordinates, so any worker computes the same bytes for
it, and the array equals one :meth:`solidsynth.Solid.region` call over the whole box. Workers
read the solid's analysis from an ``.ssa`` file, loaded once per worker process; the file must
be readable at the same path on every worker (a shared directory, ``ssa_dir``, on a real
cluster).

>>> from dask.distributed import Client                      # doctest: +SKIP
>>> import solidsynth.dask
>>> client = Client("tcp://scheduler:8786")                  # doctest: +SKIP
>>> arr = solidsynth.dask.region("marble.png", (512, 512, 512), 128, seed=7,
...                              ssa_dir="/shared/ssa")       # doctest: +SKIP
>>> arr.to_zarr("/shared/marble.zarr")                       # doctest: +SKIP

Needs ``dask[array]`` (``pip install solidsynth[dask]``).
"""

from __future__ import annotations

import functools
import hashlib
import os
import tempfile
from pathlib import Path
from typing import Any, Optional, Sequence, Tuple, Union

import numpy as np

import dask.array as da
from dask.array.core import normalize_chunks

from . import Solid, _solidsynth

__all__ = ["region"]

PathLike = Union[str, "os.PathLike[str]"]

def region(
    source: Union[PathLike, Solid],
    shape: Sequence[int],
    chunks: Any,
    origin: Sequence[int] = (0, 0, 0),
    *,
    ssa_dir: Optional[PathLike] = None,
    **solid_options: Any,
) -> da.Array:
    """The box of a solid as a Dask array of shape (Z, Y, X, C), uint8.

    ``source``: an exemplar (image path or uint8 array), an ``.ssa`` analysis path, or a
    :class:`Solid` (whose settings are then used; give no ``solid_options``). ``shape``: (Z, Y, X) voxels.
    ``chunks``: Dask chunks of those three axes (an int, a tuple, ...; the channel axis is one
    chunk). ``origin``: the solid's voxel (x, y, z) at array index [0, 0, 0]. ``ssa_dir``: where
    the analysis of an image or a Solid is written for the workers (default: the system's
    temporary directory, which only local workers see). ``solid_options``: :class:`Solid`'s
    keyword arguments.
    """
    shape = _three_ints("shape", shape, "three positive sizes (Z, Y, X)")
    if min(shape) < 1:
        raise ValueError(f"shape: expected three positive sizes (Z, Y, X), got {shape}")
    origin = _three_ints("origin", origin, "three integers (x, y, z)")
    ox, oy, oz = origin
    for axis, (lo, n) in enumerate(zip((ox, oy, oz), shape[::-1])):
        if not (-COORDINATE_LIMIT <= lo and lo + n <= COORDINATE_LIMIT):
            raise ValueError(
                f"origin {origin} with shape {shape}: the box must lie within "
                f"+-{COORDINATE_LIMIT} along {'xyz'[axis]}"
            )
    if chunks == "auto":
        # Dask's own "auto" sizes blocks by bytes and may exceed a block's side limit.
        chunks = tuple(min(n, DEFAULT_BLOCK) for n in shape)
    _check_block_count(shape, chunks)
    try:
        block_chunks = normalize_chunks(chunks, shape, dtype=np.uint8)
    except (TypeError, ValueError, ZeroDivisionError) as e:
        raise ValueError(f"chunks {chunks!r}: not Dask chunks of shape {shape} ({e})") from None
    if min(min(sides) for sides in block_chunks) < 1:
        raise ValueError(f"chunks {chunks!r}: every block needs at least one voxel a side")
    blocks = int(np.prod([len(sides) for sides in block_chunks], dtype=object))
    if blocks > MAX_BLOCKS:
        raise ValueError(
            f"shape {shape} in chunks {chunks!r}: {blocks} blocks; at most {MAX_BLOCKS} "
            f"(larger chunks, or the box in parts)"
        )
    largest = max(max(sides) for sides in block_chunks)
    if largest > MAX_BLOCK_SIDE:
        raise ValueError(
            f"chunks {chunks}: a block side of {largest} voxels; each must be at most "
            f"{MAX_BLOCK_SIDE} (one region call)"
        )
    ssa, synth_options, channels = _analysis_file(source, solid_options, ssa_dir)
    block_chunks = block_chunks + ((channels,),)
    return da.map_blocks(
        _block,
        chunks=block_chunks,
        dtype=np.uint8,
        meta=np.empty((0, 0, 0, 0), dtype=np.uint8),
        token="solidsynth-region",
        ssa=ssa,
        options=synth_options,
        origin=(ox, oy, oz),
    )


# The library's limits (`solidsynth::solid::limits`): a block is one region call.
MAX_BLOCK_SIDE = _solidsynth.MAX_BOX_SIDE
COORDINATE_LIMIT = _solidsynth.COORDINATE_LIMIT
# The block side for ``chunks="auto"``.
DEFAULT_BLOCK = 128
# The most blocks one array may have: Dask builds a task per block up front (a graph of ten
# million tasks takes minutes and gigabytes before anything runs).
MAX_BLOCKS = 1_000_000


def _check_block_count(shape: Tuple[int, int, int], chunks: Any) -> None:
    """Refuse more than MAX_BLOCKS blocks where ``chunks`` is one block side or one per axis,
    before Dask lists every block's sides (``normalize_chunks`` of 2**28 voxels in chunks of 1
    takes minutes)."""
    sides = chunks if isinstance(chunks, tuple) else (chunks,) * 3
    if len(sides) != 3 or not all(isinstance(c, (int, np.integer)) and c > 0 for c in sides):
        return
    blocks = 1
    for n, side in zip(shape, sides):
        blocks *= -(-n // int(side))
    if blocks > MAX_BLOCKS:
        raise ValueError(
            f"shape {shape} in chunks {chunks!r}: {blocks} blocks; at most {MAX_BLOCKS} "
            f"(larger chunks, or the box in parts)"
        )


def _three_ints(name: str, value: Any, expected: str) -> Tuple[int, int, int]:
    """``value`` as three Python ints (ints or NumPy integers, not bools), else ValueError."""
    try:
        items = () if isinstance(value, (str, bytes)) else tuple(value)
    except TypeError:
        items = ()
    if len(items) != 3 or not all(
        isinstance(c, (int, np.integer)) and not isinstance(c, (bool, np.bool_)) for c in items
    ):
        raise ValueError(f"{name}: expected {expected}, got {value!r}")
    return tuple(int(c) for c in items)


def _block(block_info=None, *, ssa, options, origin):
    """One block: the region of the solid under it."""
    (z0, z1), (y0, y1), (x0, x1) = block_info[None]["array-location"][:3]
    ox, oy, oz = origin
    solid = _load(ssa, options)
    return solid.region((ox + x0, oy + y0, oz + z0), (ox + x1, oy + y1, oz + z1))


@functools.lru_cache(maxsize=8)
def _load(ssa: Tuple[str, int, int], options: Tuple[Tuple[str, Any], ...]) -> Solid:
    """The solid of an analysis file, once per process (per file version and settings)."""
    return Solid.load(ssa[0], **dict(options))


def _analysis_file(source, solid_options, ssa_dir):
    """The analysis file workers load, as (path, mtime, size) (a changed file is a new cache
    key), the synthesis settings as a hashable tuple, and the channels of the blocks.

    The solid is built here, once: bad settings fail now, with the command line's messages,
    rather than in every task.
    """
    if isinstance(source, Solid):
        if solid_options:
            raise TypeError("solid_options: a Solid's own settings are used; give none")
        solid = source
    else:
        solid = Solid(source, **solid_options)
    if isinstance(source, (str, os.PathLike)) and Path(source).suffix.lower() == ".ssa":
        path = Path(source).resolve()
    else:
        path = _write_analysis(solid, ssa_dir)
    stat = path.stat()
    key = (str(path), stat.st_mtime_ns, stat.st_size)
    return key, _options_key(solid.options), solid.channels


def _options_key(options):
    """Settings as a sorted tuple, lists turned to tuples (lru_cache keys must hash)."""
    return tuple(
        sorted((k, tuple(v) if isinstance(v, list) else v) for k, v in options.items())
    )


def _write_analysis(solid: Solid, ssa_dir: Optional[PathLike]) -> Path:
    """The solid's analysis in ``ssa_dir``, named by its content (written once)."""
    directory = Path(ssa_dir) if ssa_dir is not None else (
        Path(tempfile.gettempdir()) / "solidsynth-dask"
    )
    directory.mkdir(parents=True, exist_ok=True)
    fd, staging = tempfile.mkstemp(suffix=".ssa", dir=directory)
    os.close(fd)
    try:
        solid.save_analysis(staging)
        digest = hashlib.sha256(Path(staging).read_bytes()).hexdigest()[:32]
        final = directory / f"{digest}.ssa"
        if final.exists():
            # Keep the existing file (and its mtime, part of the workers' cache key).
            return final.resolve()
        os.replace(staging, final)
        return final.resolve()
    finally:
        if os.path.exists(staging):
            os.remove(staging)
