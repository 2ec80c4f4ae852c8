"""Maps: loaded from ROS files, built from numpy arrays or ``nav_msgs/OccupancyGrid`` messages."""

from __future__ import annotations

import array as pyarray
import enum
import errno
import math
import os
import warnings
from dataclasses import dataclass
from typing import Any, Optional, Tuple, Union

import numpy as np

from . import _args, _core

PathLike = Union[str, "os.PathLike[str]"]
Origin = Tuple[float, float, float]


class State(enum.IntEnum):
    """A cell's state, as ``Map.states()`` gives it."""

    FREE = 0
    UNKNOWN = 1
    OCCUPIED = 2


def _yaw(q: Any) -> float:
    """The yaw of a quaternion with ``x, y, z, w`` attributes (geometry_msgs/Quaternion)."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def _origin(origin: Any) -> Origin:
    """(x, y, yaw) from a tuple or a geometry_msgs/Pose-like object."""
    if origin is None:
        return (0.0, 0.0, 0.0)
    if hasattr(origin, "position") and hasattr(origin, "orientation"):
        return (float(origin.position.x), float(origin.position.y), _yaw(origin.orientation))
    values = tuple(float(v) for v in origin)
    if len(values) == 2:
        return (values[0], values[1], 0.0)
    if len(values) != 3:
        raise ValueError(f"origin must be (x, y, yaw) or a Pose, got {origin!r}")
    return values  # type: ignore[return-value]


def _finite_yaw(origin: Origin, stacklevel: int = 3) -> Origin:
    """``origin`` with a non-finite yaw (NaN, inf) replaced by 0, with a warning: as the command line
    reads a yaml whose yaw is ``nan``, so that every later use (world coordinates, an OccupancyGrid's
    quaternion) is finite."""
    x, y, yaw = origin
    if math.isfinite(yaw):
        return origin
    warnings.warn(f"origin yaw is {yaw}; world coordinates use yaw 0", RuntimeWarning,
                  stacklevel=stacklevel)
    return (x, y, 0.0)


def _zero_nonfinite_yaw(origin: Origin) -> Origin:
    x, y, yaw = origin
    return origin if math.isfinite(yaw) else (x, y, 0.0)


def _grid_cells(data: Any) -> np.ndarray:
    """OccupancyGrid data as an int8 array, without a copy where the container allows it: bytes and
    ``array('b')`` (rclpy) are viewed, int8 numpy arrays (rosbags) taken as they are; other integer
    arrays and sequences are converted with a range check (values outside -128..127 are an error, never
    wrapped)."""
    if isinstance(data, (bytes, bytearray, memoryview)) or (
        isinstance(data, pyarray.array) and data.typecode == "b"
    ):
        return np.frombuffer(data, dtype=np.int8)
    if isinstance(data, np.ndarray):
        if data.dtype == np.int8:
            return data
        if data.dtype.kind not in "iu":
            raise ValueError(f"occupancy grid data must be int8 cells, got {data.dtype}")
        if data.size and (data.min() < -128 or data.max() > 127):
            raise ValueError("occupancy grid cells must lie in -128..127 (int8)")
        return data.astype(np.int8)
    try:
        # array('b') checks every value's range in C, in every Python and numpy version.
        return np.frombuffer(pyarray.array("b", data), dtype=np.int8)
    except (TypeError, OverflowError) as e:
        raise ValueError(f"occupancy grid data must be int8 cells (-128..127): {e}") from None


@dataclass(frozen=True)
class OccupancyGrid:
    """A map as ``nav_msgs/OccupancyGrid`` carries it: ``data`` int8, row 0 at the bottom, 100 occupied,
    0 free, -1 unknown; ``origin`` (x, y, yaw) of the lower-left cell's outer corner."""

    data: np.ndarray
    width: int
    height: int
    resolution: float
    origin: Origin

    @property
    def orientation(self) -> Tuple[float, float, float, float]:
        """The origin's yaw as a quaternion (x, y, z, w)."""
        half = self.origin[2] / 2.0
        return (0.0, 0.0, math.sin(half), math.cos(half))

    def fill(self, msg: Any) -> Any:
        """Writes this grid into an OccupancyGrid message (rclpy, rospy or rosbags) and returns it: its
        ``info`` (width, height, resolution, origin pose) and ``data`` (in the container type the
        message already uses)."""
        info = msg.info
        info.width, info.height, info.resolution = self.width, self.height, self.resolution
        info.origin.position.x, info.origin.position.y = self.origin[0], self.origin[1]
        info.origin.position.z = 0.0
        q = info.origin.orientation
        q.x, q.y, q.z, q.w = self.orientation
        current = getattr(msg, "data", None)
        if isinstance(current, np.ndarray):
            msg.data = self.data.copy()
        else:
            # rclpy takes array('b') for int8[] without a per-element check.
            msg.data = pyarray.array("b", self.data.tobytes())
        return msg


class Map:
    """An occupancy map: a greyscale image read as ROS ``map_server`` reads it (``occupied_thresh``,
    ``free_thresh``, ``negate``), and where it lies in the world (``resolution``, ``origin``) when known.

    Maps are immutable. ``Map(pixels)`` copies the array unless ``copy=False``, in which case it reads
    the array in place (then do not write to it while the map is used). ``load_map``,
    ``Map.from_occupancy_grid`` and ``merge`` results own their pixels; ``pixels`` is a read-only view.
    """

    __slots__ = ("_m",)

    def __init__(
        self,
        pixels: Any,
        resolution: Optional[float] = None,
        origin: Any = None,
        *,
        negate: bool = False,
        occupied_thresh: float = 0.65,
        free_thresh: float = 0.196,
        copy: bool = True,
    ) -> None:
        a = np.asarray(pixels)
        if a.dtype != np.uint8:
            hint = " (int8 occupancy grid cells: Map.from_occupancy_grid)" if a.dtype == np.int8 else ""
            raise TypeError(f"a map image is uint8 grey levels, got {a.dtype}{hint}")
        if a.ndim != 2:
            raise ValueError(f"a map image is 2-D (height, width), got shape {a.shape}")
        o = None if origin is None else _finite_yaw(_origin(origin))
        self._m = _core.Map(
            a, resolution, o, negate=negate, occupied_thresh=occupied_thresh,
            free_thresh=free_thresh, copy=copy,
        )

    @classmethod
    def _wrap(cls, m: "_core.Map") -> "Map":
        obj = cls.__new__(cls)
        obj._m = m
        return obj

    @classmethod
    def from_occupancy_grid(
        cls,
        data: Any,
        width: Optional[int] = None,
        height: Optional[int] = None,
        resolution: Optional[float] = None,
        origin: Any = None,
        *,
        occupied_thresh: float = 0.65,
        free_thresh: float = 0.25,
    ) -> "Map":
        """A map from a ``nav_msgs/OccupancyGrid`` as it arrives: ``data`` (int8 cells as a list, an
        ``array('b')``, bytes or a numpy array; -1 unknown, 0..100; row 0 at the BOTTOM), ``width``,
        ``height``, ``resolution`` and ``origin`` ((x, y, yaw) or a geometry_msgs/Pose). Or the message
        itself: ``Map.from_occupancy_grid(msg)``.

        The cells become the image ROS ``map_saver`` writes (free when 0 <= v <= 100 * free_thresh,
        occupied when v >= 100 * occupied_thresh, else unknown; its defaults), so detection and merging
        give what the command-line tool gives on the saved map.
        """
        if hasattr(data, "info") and hasattr(data, "data"):
            info = data.info
            width = info.width if width is None else width
            height = info.height if height is None else height
            resolution = info.resolution if resolution is None else resolution
            origin = info.origin if origin is None else origin
            data = data.data
        if width is None or height is None or resolution is None:
            raise TypeError("from_occupancy_grid needs width, height and resolution (or a message)")
        # A float or a string would be truncated or parsed: a grid's size is a count.
        width, height = _args.unsigned("width", width, 32), _args.unsigned("height", height, 32)
        cells = _grid_cells(data)
        cells = np.ascontiguousarray(cells.reshape(-1)).view(np.uint8)
        # MapMetaData.resolution is a float32: 0.05 arrives as 0.05000000074505806. Its shortest float32
        # form is what the map's author wrote, and what a saved yaml should say.
        resolution = float(str(np.float32(resolution)))
        return cls._wrap(
            _core.Map._from_grid(
                cells, width, height, float(resolution), _origin(origin),
                occupied_thresh, free_thresh,
            )
        )

    def to_occupancy_grid(self) -> OccupancyGrid:
        """The map as ``nav_msgs/OccupancyGrid`` data, as ``map_server`` publishes a trinary map (row 0 at
        the bottom, 100 occupied, 0 free, -1 unknown); ``OccupancyGrid.fill(msg)`` writes it into a
        message. A map with no georeference gets resolution 1 and origin 0 (placeholders)."""
        return OccupancyGrid(
            data=self._m._grid_cells(),
            width=self.width,
            height=self.height,
            resolution=self.resolution or 1.0,
            # A yaml's `nan` yaw (said in `warnings` when loaded) is read as 0, as everywhere else.
            origin=_zero_nonfinite_yaw(self.origin or (0.0, 0.0, 0.0)),
        )

    @property
    def pixels(self) -> np.ndarray:
        """The grey levels, (height, width) uint8, read-only, sharing the map's memory."""
        return self._m.pixels

    @property
    def width(self) -> int:
        return self._m.width

    @property
    def height(self) -> int:
        return self._m.height

    @property
    def shape(self) -> Tuple[int, int]:
        """(height, width), as numpy has it."""
        return (self._m.height, self._m.width)

    @property
    def resolution(self) -> Optional[float]:
        """Metres a pixel, or None with no georeference."""
        return self._m.resolution

    @property
    def origin(self) -> Optional[Origin]:
        """(x, y, yaw) of the lower-left pixel's outer corner (metres, radians), or None."""
        return self._m.origin

    @property
    def thresholds(self) -> Tuple[bool, float, float]:
        """(negate, occupied_thresh, free_thresh)."""
        return self._m.thresholds

    @property
    def source(self) -> Optional[str]:
        """The file the map came from (its yaml, else its image), or None."""
        s = self._m.source
        return None if s is None else os.fspath(s)

    @property
    def warnings(self) -> list:
        """What loading noticed that did not stop it."""
        return self._m.warnings

    def states(self) -> np.ndarray:
        """Each pixel's ``State`` as (height, width) uint8: 0 free, 1 unknown, 2 occupied."""
        return self._m.states()

    def save(self, path: PathLike) -> None:
        """Writes ``NAME.yaml`` (with ``NAME.pgm`` beside it) or ``NAME.pgm`` alone, atomically."""
        self._m.save(os.fspath(path))

    def with_georef(self, resolution: float, origin: Any = None) -> "Map":
        """The same pixels (not copied) with another resolution and origin."""
        o = None if origin is None else _finite_yaw(_origin(origin))
        return Map._wrap(self._m.with_georef(resolution, o))

    def pixel_to_world(self, x: Any, y: Any) -> Tuple[np.ndarray, np.ndarray]:
        """World coordinates (metres) of pixel centres (x, y), rows counted from the top."""
        if self.resolution is None:
            raise ValueError("the map has no georeference (resolution and origin)")
        ox, oy, yaw = self.origin  # type: ignore[misc]
        yaw = yaw if math.isfinite(yaw) else 0.0
        mx = (np.asarray(x, dtype=np.float64) + 0.5) * self.resolution
        my = (self.height - 1 - np.asarray(y, dtype=np.float64) + 0.5) * self.resolution
        c, s = math.cos(yaw), math.sin(yaw)
        return ox + c * mx - s * my, oy + s * mx + c * my

    def __reduce__(self) -> Any:
        # Pickled (multiprocessing, joblib) as its pixels, georeference, thresholds, the files it came
        # from (a merge names the map by them) and what loading noticed.
        negate, occupied, free = self.thresholds
        kwargs = {"negate": negate, "occupied_thresh": occupied, "free_thresh": free}
        files = self._m._files()
        return (_unpickle, (np.array(self.pixels), self.resolution, self.origin, kwargs, files))

    def __repr__(self) -> str:
        return repr(self._m)


def _unpickle(pixels: np.ndarray, resolution: Optional[float], origin: Any, kwargs: dict,
              files: Any = None) -> Map:
    # A loaded map's `nan` yaw was said when it was loaded (its warnings come along): not again.
    origin = None if origin is None else _zero_nonfinite_yaw(tuple(origin))
    m = Map(pixels, resolution, origin, copy=False, **kwargs)
    if files is not None:
        m._m = m._m._with_files(*files)
    return m


def load_map(path: PathLike) -> Map:
    """Loads a ROS ``map_server`` yaml (and the image it names) or an image alone (PGM or PNG, with the
    ROS default thresholds and no georeference)."""
    p = os.fsdecode(os.fspath(path))
    if not os.path.exists(p):
        raise FileNotFoundError(errno.ENOENT, "no such map", p)
    return Map._wrap(_core.load_map(p))
