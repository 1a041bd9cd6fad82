"""Type stubs of the native module (``python/src/lib.rs``)."""

import os
from typing import Any, Dict, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

__version__: str
# The largest side of a box made in one call, and the coordinates a box may reach (+-).
MAX_BOX_SIDE: int
COORDINATE_LIMIT: int

# A path, or pixels: (H, W) or (H, W, C) uint8, C in 1 (gray), 3 (RGB), 4 (RGBA).
_Picture = Union[str, "os.PathLike[str]", npt.NDArray[np.uint8]]
_Point = Sequence[float]
_Voxel = Sequence[int]

class Error(Exception):
    """A failure that is not the caller's input (no GPU, a GPU error or timeout, an internal
    error); bad input raises ValueError (a wrong type: TypeError), an unreadable file an
    OSError."""

class Solid:
    """A solid texture: a deterministic function over all of Z^3.

    ``exemplar`` is an image path, a uint8 array (H, W) or (H, W, C), an ``.ssa`` analysis
    file, or None for the built-in exemplar; ``ey`` and ``ez`` (together) are the exemplars of
    the planes orthogonal to y and z. The keyword arguments are the command line's flags of the
    same names (``feature_mask`` is ``--feature-mask``), with its defaults; None means the
    command line's default. ``cache``: the user's analysis cache (True), none (False), or a
    directory.
    """

    def __init__(
        self,
        exemplar: Optional[_Picture] = None,
        *,
        ey: Optional[_Picture] = None,
        ez: Optional[_Picture] = None,
        seed: int = 0,
        jitter: float = 1.0,
        backend: str = "auto",
        adapter: Optional[str] = None,
        candidates: str = "3d",
        passes: Union[int, str, Sequence[int]] = 2,
        color: str = "average",
        coarse_cache: Optional[int] = None,
        max_group: Optional[int] = None,
        frame: Optional[str] = None,
        feature_mask: Optional[Union[str, _Picture]] = None,
        ey_feature_mask: Optional[_Picture] = None,
        ez_feature_mask: Optional[_Picture] = None,
        feature_weight: Optional[float] = None,
        periodic: bool = False,
        balance_rounds: Optional[int] = None,
        balance_strength: float = 1.0,
        cache: Union[bool, str, "os.PathLike[str]"] = True,
    ) -> None: ...
    @staticmethod
    def load(
        path: Union[str, "os.PathLike[str]"],
        *,
        seed: int = 0,
        jitter: float = 1.0,
        backend: str = "auto",
        adapter: Optional[str] = None,
        candidates: str = "3d",
        passes: Union[int, str, Sequence[int]] = 2,
        color: str = "average",
        coarse_cache: Optional[int] = None,
        max_group: Optional[int] = None,
    ) -> "Solid":
        """The solid of an ``.ssa`` analysis file with these synthesis settings."""
    def region(self, lo: _Voxel, hi: _Voxel) -> npt.NDArray[np.uint8]:
        """The half-open box [lo, hi) ((x, y, z) corners, any coordinates) as (Z, Y, X, C)."""
    def tileable(self, n: int) -> npt.NDArray[np.uint8]:
        """The n^3 tileable solid (n a multiple of 32) as (n, n, n, C)."""
    def cut(
        self,
        origin: _Point,
        normal: _Point,
        up: Optional[_Point] = None,
        size: int = 256,
        spacing: float = 1.0,
    ) -> npt.NDArray[np.uint8]:
        """A planar cut of ``size`` x ``size`` pixels, ``spacing`` voxels apart, as (size, size, C).

        Pixel [j, i] samples origin + (i + 0.5 - size/2) * spacing * u + (j + 0.5 - size/2) *
        spacing * v: v is ``up`` projected onto the plane (default +y; +z for a normal along y),
        u = v x normal. For normal (0, 0, 1) the array is [y, x], like a z slice of ``region``.
        """
    def save_analysis(self, path: Union[str, "os.PathLike[str]"]) -> None:
        """Write the analysis as an ``.ssa`` file (what ``solidsynth analyze`` writes)."""
    @property
    def channels(self) -> int:
        """Colour channels of the arrays returned."""
    @property
    def backend(self) -> str:
        """The backend the kernels run on, described."""
    @property
    def options(self) -> Dict[str, Any]:
        """The synthesis settings, as :meth:`load` takes them."""

def eval(
    exemplar: _Picture,
    volume: Union[str, "os.PathLike[str]", npt.NDArray[np.uint8]],
    *,
    ey: Optional[_Picture] = None,
    ez: Optional[_Picture] = None,
    frame: Optional[str] = None,
    slices: int = 3,
    seed: int = 1,
) -> Dict[str, Any]:
    """Score a volume (NRRD path, or (Z, Y, X[, C]) uint8) against its exemplar: the document
    of ``solidsynth eval --json``."""

