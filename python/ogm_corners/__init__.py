"""Corners in robot occupancy grid maps, and map merging with no initial poses.

The OGM corner detector of "A New Corner Detector Approach for Occupancy Grid Map Merging" and its
robust form, the paper's baselines (Harris, Shi-Tomasi, Trajkovic-Hedley), on the CPU or any GPU wgpu
drives, bit-identical between them; and a merger of many robots' maps that declines rather than guess.

    import ogm_corners as oc
    m = oc.load_map("map.yaml")              # or oc.Map.from_occupancy_grid(msg)
    kp = oc.detect(m, detector="ogm-robust")  # kp.x, kp.y, kp.world, kp.array (structured)
    al = oc.merge(m, oc.load_map("other.yaml"))
    if al.accepted:
        merged = oc.compose(m, "other.yaml", al)
"""

import os as _os
import warnings as _warnings

# Without a desktop session, Mesa's Vulkan device-selection layer asks Wayland for the display's GPU
# when adapters are listed, and Wayland prints "error: XDG_RUNTIME_DIR is invalid or not set" however
# well the call goes; with no display there is nothing to select by (as the command line does).
_session = _os.environ.get("XDG_RUNTIME_DIR")
if not (_session and _os.path.isdir(_session)):
    _os.environ.setdefault("NODEVICE_SELECT", "1")

from . import _core
from ._core import BackendUnavailableError

if _core._THREADS_NOTE is not None:
    _warnings.warn(_core._THREADS_NOTE, RuntimeWarning, stacklevel=2)
from ._detect import BACKENDS, DETECTORS, Detector, detect
from ._keypoints import DTYPE, DTYPE_WORLD, Keypoints
from ._map import Map, OccupancyGrid, State, load_map
from ._merge import (
    Alignment,
    ManyMerge,
    MergeCache,
    Pose,
    WorldTransform,
    compose,
    merge,
    merge_many,
    overlay,
    rigid_matrix,
)
from . import distributed, synthetic

__version__: str = _core.__version__

__all__ = [
    "Alignment",
    "BACKENDS",
    "BackendUnavailableError",
    "DETECTORS",
    "DTYPE",
    "DTYPE_WORLD",
    "Detector",
    "Keypoints",
    "ManyMerge",
    "Map",
    "OccupancyGrid",
    "Pose",
    "State",
    "WorldTransform",
    "compose",
    "detect",
    "distributed",
    "load_map",
    "merge",
    "MergeCache",
    "merge_many",
    "overlay",
    "rigid_matrix",
    "synthetic",
]
