# Types of the compiled module (python/src/*.rs). The public API is the package around it; these are
# its building blocks, not meant to be called directly.
from os import PathLike
from typing import Any, List, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str
#: The most `partners` a many-map merge takes.
MAX_PARTNERS: int
_THREADS_NOTE: Optional[str]

_Path = Union[str, PathLike[str]]
_Origin = Tuple[float, float, float]
_Transform = Tuple[float, float, float]

class BackendUnavailableError(RuntimeError): ...

class Map:
    def __init__(
        self,
        pixels: npt.NDArray[np.uint8],
        resolution: Optional[float] = None,
        origin: Optional[_Origin] = None,
        *,
        negate: bool = False,
        occupied_thresh: float = 0.65,
        free_thresh: float = 0.196,
        copy: bool = True,
    ) -> None: ...
    @staticmethod
    def _from_grid(
        cells: npt.NDArray[np.uint8],
        width: int,
        height: int,
        resolution: float,
        origin: _Origin,
        occupied_thresh: float = 0.65,
        free_thresh: float = 0.25,
    ) -> Map: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def resolution(self) -> Optional[float]: ...
    @property
    def origin(self) -> Optional[_Origin]: ...
    @property
    def thresholds(self) -> Tuple[bool, float, float]: ...
    @property
    def source(self) -> Optional[str]: ...
    @property
    def warnings(self) -> List[str]: ...
    @property
    def pixels(self) -> npt.NDArray[np.uint8]: ...
    def states(self) -> npt.NDArray[np.uint8]: ...
    def _grid_cells(self) -> npt.NDArray[np.int8]: ...
    def save(self, path: _Path) -> None: ...
    def with_georef(self, resolution: float, origin: Optional[_Origin] = None) -> Map: ...
    def _files(self) -> Tuple[Optional[str], Optional[str], List[str]]: ...
    def _with_files(self, yaml: Optional[_Path], image: Optional[_Path], warnings: List[str]) -> Map: ...

class Detector:
    def __init__(
        self,
        detector: str = "ogm",
        backend: str = "auto",
        *,
        rules: str = "paper",
        unknown_as_occupied: bool = False,
        max_corners: Optional[int] = None,
        sigma: float = 1.0,
        harris_k: float = 0.04,
        quality: float = 0.01,
        min_distance: float = 3.0,
        t1: int = 10000,
        t2: int = 20000,
        min_scale: Optional[int] = None,
        max_scale: Optional[int] = None,
        angle: Optional[float] = None,
        anchor: Union[str, Tuple[float, float], None] = None,
        nms_radius: Optional[int] = None,
        min_strength: Optional[int] = None,
        convex: bool = True,
        cell_occupied: Optional[int] = None,
        cell_free: Optional[int] = None,
        wall_gap: Optional[int] = None,
    ) -> None: ...
    @property
    def backend(self) -> str: ...
    @property
    def backend_note(self) -> Optional[str]: ...
    @property
    def detector(self) -> str: ...
    def _detect_map(self, map: Map) -> Tuple[npt.NDArray[np.uint64], Optional[float]]: ...
    def _time_rust(self, map: Map) -> float: ...
    def _detect_array(
        self,
        pixels: npt.NDArray[np.uint8],
        grid: bool,
        occupied_thresh: float = 0.65,
        free_thresh: float = 0.25,
    ) -> Tuple[npt.NDArray[np.uint64], Optional[float]]: ...

class ManyMerge:
    def _report(self) -> str: ...
    def _merged(self, g: int) -> Map: ...
    def _overlay(self, g: int) -> npt.NDArray[np.uint8]: ...
    def _parts(self) -> Tuple[str, List[Map], List[List[int]], List[_Transform]]: ...
    @staticmethod
    def _from_parts(
        report: str, maps: List[Map], groups: List[List[int]], poses: List[_Transform]
    ) -> ManyMerge: ...

def load_map(path: _Path) -> Map: ...
def synthetic_office(
    width: int = 1024, height: int = 768, seed: int = 1, resolution: float = 0.05
) -> Map: ...
def synthetic_robot_maps(
    source: Map, n: int, noise: float = 0.0, seed: int = 1
) -> List[Tuple[Map, _Transform]]: ...
def synthetic_fleet(n: int, buildings: int = 4, seed: int = 1) -> List[Tuple[str, Map]]: ...
def merge(a: Map, b: Map, backend: str = "cpu") -> str: ...
def compose(a: Map, b: Map, transform: _Transform) -> Map: ...
def overlay(a: Map, b: Map, transform: _Transform) -> npt.NDArray[np.uint8]: ...
class MergeCache:
    def __init__(self) -> None: ...
    def _last_use(self) -> Tuple[int, int, int, int]: ...

def merge_many(
    maps: List[Map],
    names: List[str],
    backend: str = "cpu",
    cache: Optional[MergeCache] = None,
    partners: int = 3,
) -> ManyMerge: ...
def merge_many_on(
    maps: List[Map],
    names: List[str],
    executor: Any,
    backend: str = "cpu",
    partners: int = 3,
) -> ManyMerge: ...
def _prepare_encoded(
    pixels: npt.NDArray[np.uint8],
    negate: bool,
    occupied_thresh: float,
    free_thresh: float,
    signature: bool,
) -> Tuple[bytes, bytes, Optional[bytes]]: ...
def _align_encoded(a: bytes, b: bytes, options: str) -> str: ...
