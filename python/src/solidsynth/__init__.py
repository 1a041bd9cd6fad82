"""Solid textures from 2D exemplar images, as NumPy arrays.

A :class:`Solid` is a deterministic function over all of Z^3, made from an exemplar image (its
analysis) and a seed: any box of it (:meth:`Solid.region`), a tileable volume
(:meth:`Solid.tileable`) or a planar cut at any angle (:meth:`Solid.cut`) is synthesized on
demand, with the same voxels whichever part asked for them. The same settings give the same
bytes as the ``solidsynth`` command line.

>>> import solidsynth
>>> solid = solidsynth.Solid("marble.png", seed=7)        # doctest: +SKIP
>>> block = solid.region((-16, 0, 100), (16, 32, 132))    # doctest: +SKIP
>>> block.shape                                           # doctest: +SKIP
(32, 32, 32, 3)

Bad input raises :class:`ValueError` (an argument of the wrong type: a :class:`TypeError`; a file
that cannot be read: an :class:`OSError`) with the command line's message; other failures raise :class:`solidsynth.Error`. Long calls release the
GIL; syntheses stop on Ctrl-C (:class:`KeyboardInterrupt`; the analysis, ``eval`` and ``.ssa``
reading and writing finish first). :mod:`solidsynth.dask` builds Dask arrays
of solids (``pip install solidsynth[dask]``).
"""

import os as _os

# Mesa's implicit Vulkan layer VK_LAYER_MESA_device_select connects to the display server to
# rank GPUs; on a headless machine libwayland then prints "error: XDG_RUNTIME_DIR is invalid or
# not set" whenever Vulkan is probed. solidsynth ranks the adapters itself, so the layer is
# skipped, as the command line skips it, unless the user set NODEVICE_SELECT.
_os.environ.setdefault("NODEVICE_SELECT", "1")

from ._solidsynth import Error, Solid, __version__  # noqa: E402
from ._solidsynth import eval  # noqa: A004,E402 - named after `solidsynth eval`

__all__ = ["Error", "Solid", "eval", "__version__"]
