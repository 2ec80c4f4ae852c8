"""Detection: ``Detector`` (keeps its backend) and ``detect`` (one call)."""

from __future__ import annotations

import math
import os
import threading
from typing import Any, Dict, Optional, Tuple

import numpy as np

from . import _args, _core
from ._keypoints import Keypoints
from ._map import Map, load_map

DETECTORS = ("ogm", "ogm-robust", "harris", "shi-tomasi", "trajkovic")
BACKENDS = ("auto", "cpu", "reference", "gpu")


# Integer options and their width: checked here so that a bad value is a ValueError naming the option
# (the extension's conversion would raise an OverflowError that names nothing).
_UNSIGNED = {
    "t1": 32, "t2": 32, "min_scale": 32, "max_scale": 32, "nms_radius": 32, "min_strength": 32,
    "cell_occupied": 32, "cell_free": 32, "wall_gap": 32, "max_corners": 63,
}


class Detector:
    """A detector and its backend, set up once and reused (a GPU's device and pipelines are created
    when the detector is). Safe to share between threads: calls take turns.

    ``detector``: ``"ogm"`` (the paper's), ``"ogm-robust"`` (turned to the walls, several scales, ranked
    by strength), ``"harris"``, ``"shi-tomasi"``, ``"trajkovic"``. ``backend``: ``"auto"`` (a hardware
    GPU when there is one, else the CPU), ``"cpu"`` (all cores), ``"reference"`` (the plain oracle),
    ``"gpu"`` (any adapter, software ones included; ``BackendUnavailableError`` without one).

    Options, as the command line's: ``rules`` (``"paper"``, ``"paper-mod2"``), ``unknown_as_occupied``;
    ``max_corners`` (strongest first; the paper's detector refuses a cap it would exceed); Harris and
    Shi-Tomasi ``sigma``, ``harris_k``, ``quality``, ``min_distance``; Trajkovic ``t1``, ``t2``; the robust
    detector's ``min_scale``, ``max_scale``, ``angle`` (degrees), ``nms_radius``, ``min_strength``,
    ``convex``, ``cell_occupied`` and ``cell_free`` (percent of a coarse cell's samples), ``wall_gap``,
    and ``anchor``: where its turned grid is anchored, ``"world"`` (the default: the origin of a map's
    world frame, its centre for an array), ``"centre"`` or a point ``(x, y)`` in pixels. Anchored in the
    world, a map that grows at its edges (as a SLAM map does) or is cropped keeps its keypoints wherever
    both see a corner's walls, given the same ``angle`` (``Keypoints.angle`` of an earlier detection).
    """

    __slots__ = ("_d",)

    def __init__(self, detector: str = "ogm", backend: str = "auto", **options: Any) -> None:
        for name, bits in _UNSIGNED.items():
            if options.get(name) is not None:
                options[name] = _args.unsigned(name, options[name], bits)
        self._d = _core.Detector(detector, backend, **options)

    @property
    def detector(self) -> str:
        """The detector's name."""
        return self._d.detector

    @property
    def backend(self) -> str:
        """The backend's name."""
        return self._d.backend

    @property
    def backend_note(self) -> Optional[str]:
        """With ``backend="auto"``: which backend it picked and why."""
        return self._d.backend_note

    def detect(
        self,
        map: Any,
        *,
        occupied_thresh: Optional[float] = None,
        free_thresh: Optional[float] = None,
    ) -> Keypoints:
        """The keypoints of ``map``: a ``Map``, a path to a map file, or a 2-D numpy array.

        A uint8 array is a map image (grey levels read with the ROS defaults; row 0 at the top); an int8
        array is ``nav_msgs/OccupancyGrid`` cells (-1 unknown, 0..100) read as ``map_saver`` reads them
        with ``occupied_thresh`` and ``free_thresh`` (0.65 and 0.25 by default; for int8 arrays only: a
        ``Map`` or a uint8 image carries its own), in the array's own row order. Either way ``x``,
        ``y`` index the array as ``array[y, x]``. A C-contiguous array is read in place (do not write to
        it during the call); any other is copied once.
        """
        if isinstance(map, (str, bytes, os.PathLike)):
            map = load_map(map)
        if not isinstance(map, Map) and getattr(np.asarray(map), "dtype", None) == np.int8:
            occupied_thresh = 0.65 if occupied_thresh is None else float(occupied_thresh)
            free_thresh = 0.25 if free_thresh is None else float(free_thresh)
            if not (math.isfinite(occupied_thresh) and math.isfinite(free_thresh)):
                raise ValueError(
                    f"occupied_thresh and free_thresh must be finite, got {occupied_thresh} and "
                    f"{free_thresh}"
                )
        elif occupied_thresh is not None or free_thresh is not None:
            raise ValueError(
                "occupied_thresh and free_thresh apply to int8 occupancy-grid arrays; a Map or a uint8 "
                "image is read with its own thresholds (Map(..., occupied_thresh=, free_thresh=))"
            )
        if isinstance(map, Map):
            words, angle = self._d._detect_map(map._m)
            return Keypoints._from_words(
                words, map.resolution is not None, self.detector, self.backend, angle,
                map.width, map.height,
            )
        a = np.asarray(map)
        if a.ndim != 2:
            raise ValueError(f"a map array is 2-D (height, width), got shape {a.shape}")
        if a.dtype == np.int8:
            grid = True
        elif a.dtype == np.uint8:
            grid = False
        else:
            raise TypeError(
                f"a map array is uint8 (grey levels) or int8 (occupancy grid cells), got {a.dtype}"
            )
        if not a.flags.c_contiguous:
            a = np.ascontiguousarray(a)
        words, angle = self._d._detect_array(
            a.view(np.uint8),
            grid,
            0.65 if occupied_thresh is None else occupied_thresh,
            0.25 if free_thresh is None else free_thresh,
        )
        return Keypoints._from_words(
            words, False, self.detector, self.backend, angle, a.shape[1], a.shape[0]
        )

    def __repr__(self) -> str:
        return f"Detector({self.detector!r}, backend={self.backend!r})"


# detect()'s detectors, one per set of options, so that a backend (a GPU above all) is opened once.
_CACHE: Dict[Tuple[Any, ...], Detector] = {}
_CACHE_LOCK = threading.Lock()
_CACHE_SIZE = 8


def detect(
    map: Any, detector: str = "ogm", backend: str = "auto", **options: Any
) -> Keypoints:
    """Detects corners in ``map`` (a ``Map``, a path, or a uint8 / int8 numpy array; see
    ``Detector.detect``) with ``detector`` on ``backend`` and the ``Detector``'s options.

    The detector and its backend are kept for the next call with the same options; keep a ``Detector``
    yourself to control that.
    """
    thresholds = {k: options.pop(k) for k in ("occupied_thresh", "free_thresh") if k in options}
    key = (detector, backend, tuple(sorted(options.items())))
    with _CACHE_LOCK:
        d = _CACHE.get(key)
    if d is None:
        d = Detector(detector, backend, **options)
        with _CACHE_LOCK:
            if len(_CACHE) >= _CACHE_SIZE:
                _CACHE.pop(next(iter(_CACHE)))
            _CACHE[key] = d
    return d.detect(map, **thresholds)
