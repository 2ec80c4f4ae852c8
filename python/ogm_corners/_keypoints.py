"""Keypoints: a numpy structured array with the detection's context."""

from __future__ import annotations

from typing import Any, Iterator, Optional, Union

import numpy as np

# The layout of `python/src/detect.rs`'s `Record`: 40 bytes, native byte order.
_FIELDS = [
    ("x", np.uint32, 0),
    ("y", np.uint32, 4),
    ("rule", np.uint8, 8),
    ("code", np.uint8, 9),
    ("scale", np.uint8, 10),
    ("convex", np.bool_, 11),
    ("score", np.int64, 16),
    ("world_x", np.float64, 24),
    ("world_y", np.float64, 32),
]
_ITEMSIZE = 40


def _dtype(world: bool) -> np.dtype:
    fields = [f for f in _FIELDS if world or not f[0].startswith("world")]
    return np.dtype(
        {
            "names": [f[0] for f in fields],
            "formats": [f[1] for f in fields],
            "offsets": [f[2] for f in fields],
            "itemsize": _ITEMSIZE,
        }
    )


#: The keypoint dtype of a georeferenced map (with ``world_x``, ``world_y`` in metres).
DTYPE_WORLD = _dtype(True)
#: The keypoint dtype of a map with no georeference (no world fields).
DTYPE = _dtype(False)


class Keypoints:
    """The keypoints of one detection, sorted by (y, x).

    ``array`` is a numpy structured array with fields ``x``, ``y`` (pixel column and row: for a ``Map``
    row 0 is the image's top row, as in the command-line tool; for an array they index it as
    ``array[y, x]``), ``rule`` (4, 5 or 6: the rule that fired; 0 for the baselines), ``code`` (the
    8-neighbour code), ``score`` (the baselines' response, the robust detector's strength in pixels; 0
    for the paper's detector), ``scale`` and ``convex`` (the robust detector), and ``world_x``,
    ``world_y`` (metres, cell centres) when the map is georeferenced.

    Columns read as attributes (``kp.x``) or items (``kp["x"]``); an index, slice or mask gives
    ``Keypoints`` again; ``np.asarray(kp)`` is the structured array (``pandas.DataFrame(kp.array)``).
    """

    __slots__ = ("array", "detector", "backend", "angle", "width", "height")

    def __init__(
        self,
        array: np.ndarray,
        detector: str,
        backend: str,
        angle: Optional[float],
        width: int,
        height: int,
    ) -> None:
        self.array = array
        #: The detector's name.
        self.detector = detector
        #: The backend that ran it.
        self.backend = backend
        #: The robust detector's grid angle in degrees (None for the others).
        self.angle = angle
        #: The map's size.
        self.width = width
        self.height = height

    @classmethod
    def _from_words(
        cls, words: np.ndarray, world: bool, detector: str, backend: str,
        angle: Optional[float], width: int, height: int,
    ) -> "Keypoints":
        # The uint64 words are the records' bytes (no copy): viewed through the dtype.
        array = words.view(DTYPE_WORLD if world else DTYPE)
        return cls(array, detector, backend, angle, width, height)

    def _like(self, array: np.ndarray) -> "Keypoints":
        return Keypoints(array, self.detector, self.backend, self.angle, self.width, self.height)

    def __len__(self) -> int:
        return len(self.array)

    def __iter__(self) -> Iterator[Any]:
        return iter(self.array)

    def __getitem__(self, key: Union[str, int, slice, np.ndarray]) -> Any:
        if isinstance(key, str):
            return self.array[key]
        got = self.array[key]
        return self._like(got) if isinstance(got, np.ndarray) else got

    def __array__(self, dtype: Any = None, copy: Optional[bool] = None) -> np.ndarray:
        if dtype is None and not copy:
            return self.array
        return np.array(self.array, dtype=dtype, copy=True)

    def __repr__(self) -> str:
        angle = "" if self.angle is None else f", angle={self.angle:.2f}"
        return (
            f"Keypoints({len(self)} {self.detector} keypoints in a {self.width}x{self.height} map, "
            f"backend={self.backend!r}{angle})"
        )

    @property
    def has_world(self) -> bool:
        """Whether the keypoints carry world coordinates (the map is georeferenced)."""
        return "world_x" in self.array.dtype.names

    @property
    def x(self) -> np.ndarray:
        """Pixel columns."""
        return self.array["x"]

    @property
    def y(self) -> np.ndarray:
        """Pixel rows."""
        return self.array["y"]

    @property
    def rule(self) -> np.ndarray:
        """The rule that fired (4, 5, 6; 0 for the baselines)."""
        return self.array["rule"]

    @property
    def code(self) -> np.ndarray:
        """The 8-neighbour code."""
        return self.array["code"]

    @property
    def score(self) -> np.ndarray:
        """The baselines' response, the robust detector's strength (pixels); 0 for the paper's detector."""
        return self.array["score"]

    @property
    def scale(self) -> np.ndarray:
        """The robust detector's coarse scale; 1 otherwise."""
        return self.array["scale"]

    @property
    def convex(self) -> np.ndarray:
        """The robust detector's convex corners."""
        return self.array["convex"]

    @property
    def xy(self) -> np.ndarray:
        """(N, 2) pixel positions, x then y."""
        return np.column_stack((self.array["x"], self.array["y"]))

    @property
    def world(self) -> Optional[np.ndarray]:
        """(N, 2) world positions in metres, or None when the map has no georeference."""
        if not self.has_world:
            return None
        return np.column_stack((self.array["world_x"], self.array["world_y"]))
