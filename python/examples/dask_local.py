"""A solid synthesized block by block on a local Dask cluster, written to Zarr, and checked
against one `Solid.region` call over the whole box, byte for byte.

    python python/examples/dask_local.py [--size 96] [--chunk 32] [--exemplar IMAGE] [--seed 5]

Two worker processes of one thread each compute the blocks: a block's voxels depend only on its
coordinates, so whichever worker computes it, the array is the solid. Exits 1 when the Zarr
array differs from the single region. Needs `pip install './python[dask]'` (from the repository
root).
"""

import argparse
import sys
import tempfile
from pathlib import Path
from typing import Any, Optional

import numpy as np


def run(
    size: int = 96,
    chunk: int = 32,
    exemplar: Optional[str] = None,
    workers: int = 2,
    **solid_options: Any,
) -> bool:
    """Synthesize [0, size)^3 on `workers` local worker processes in chunks of `chunk`, write it
    to Zarr in a temporary directory, and say whether it equals one `region` call."""
    import zarr
    from dask.distributed import Client, LocalCluster

    import solidsynth
    import solidsynth.dask

    solid = solidsynth.Solid(exemplar, **solid_options)
    with tempfile.TemporaryDirectory() as tmp:
        store = str(Path(tmp) / "solid.zarr")
        with LocalCluster(
            n_workers=workers,
            processes=True,
            threads_per_worker=1,
            dashboard_address=None,
        ) as cluster, Client(cluster):
            # The analysis goes to `tmp`, which these local workers read; on a real cluster,
            # give a shared directory.
            array = solidsynth.dask.region(solid, (size, size, size), chunk, ssa_dir=tmp)
            array.to_zarr(store)
        written = np.asarray(zarr.open_array(store, mode="r")[...])
    whole = solid.region((0, 0, 0), (size, size, size))
    same = written.shape == whole.shape and written.tobytes() == whole.tobytes()
    print(
        f"{size}^3 in chunks of {chunk} on {workers} workers -> Zarr {written.shape}: "
        + ("the same bytes as one region call" if same else "DIFFERENT from one region call")
    )
    return same


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=96)
    parser.add_argument("--chunk", type=int, default=32)
    parser.add_argument("--exemplar", help="exemplar image (default: the built-in one)")
    parser.add_argument("--seed", type=int, default=5)
    parser.add_argument("--backend", default="auto", choices=["auto", "cpu", "gpu"])
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args(argv)
    same = run(
        size=args.size,
        chunk=args.chunk,
        exemplar=args.exemplar,
        workers=args.workers,
        seed=args.seed,
        backend=args.backend,
    )
    return 0 if same else 1


# The guard matters: worker processes are spawned and import this file.
if __name__ == "__main__":
    sys.exit(main())
