"""Merging maps with no initial poses: two (``merge``, ``compose``, ``overlay``) or many (``merge_many``)."""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from typing import Any, Dict, Iterator, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import _args, _core
from ._map import Map, load_map


def _rigid_matrix(theta: float, tx: float, ty: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s, tx], [s, c, ty], [0.0, 0.0, 1.0]])


def rigid_matrix(theta_deg: float, tx: float, ty: float) -> np.ndarray:
    """The 3x3 homogeneous matrix of a pixel transform ``(theta_deg, tx, ty)`` as ``Alignment``,
    ``Pose`` and ``synthetic.robot_maps`` give them: ``p' = R(theta) p + t``, x right, y down."""
    return _rigid_matrix(math.radians(theta_deg), tx, ty)


@dataclass(frozen=True)
class WorldTransform:
    """A pose in a map frame, metres and radians (ROS: x east, y north, yaw counter-clockwise):
    ``w_a = R(yaw) w_b + (x, y)``."""

    x: float
    y: float
    yaw: float

    @property
    def matrix(self) -> np.ndarray:
        """The 3x3 homogeneous matrix."""
        return _rigid_matrix(self.yaw, self.x, self.y)


def _world(d: Optional[Dict[str, float]]) -> Optional[WorldTransform]:
    return None if d is None else WorldTransform(x=d["x"], y=d["y"], yaw=d["yaw"])


@dataclass(frozen=True)
class Alignment:
    """The verdict on map B aligned onto map A (``merge``).

    ``theta_deg``, ``tx``, ``ty``: B's pixels to A's pixels, ``p_a = R(theta) p_b + t`` (x right, y down,
    pixel centres at integers; B at A's resolution, ``b_scale`` its resolution over A's). ``world``: the
    pose of B's map frame in A's when both are georeferenced. ``accepted`` is False with a ``reason``
    when the merger is not confident; the transform is then its best guess and must not be used.
    """

    accepted: bool
    reason: Optional[str]
    theta_deg: float
    tx: float
    ty: float
    score: float
    overlap: float
    b_scale: float
    world: Optional[WorldTransform]
    features: Dict[str, float] = field(repr=False)

    @property
    def theta(self) -> float:
        """The turn in radians (pixel frame: positive turns clockwise on screen, y pointing down)."""
        return math.radians(self.theta_deg)

    @property
    def matrix(self) -> np.ndarray:
        """The 3x3 matrix from B's pixels (at A's resolution) to A's."""
        return rigid_matrix(self.theta_deg, self.tx, self.ty)

    @property
    def transform(self) -> Tuple[float, float, float]:
        """(theta_deg, tx, ty)."""
        return (self.theta_deg, self.tx, self.ty)


def _as_map(m: Any) -> Map:
    if isinstance(m, Map):
        return m
    if isinstance(m, (str, bytes, os.PathLike)):
        return load_map(m)
    raise TypeError(f"expected a Map or a path, got {type(m).__name__}")


def merge(a: Any, b: Any, *, backend: str = "cpu") -> Alignment:
    """Aligns map ``b`` onto map ``a`` with no initial pose and says whether it is confident.

    ``a`` and ``b`` are ``Map`` objects or paths. ``backend`` scores the candidates (the same verdict on
    every backend; the CPU by default: a pair is less work than opening a GPU).
    """
    ma, mb = _as_map(a), _as_map(b)
    d = json.loads(_core.merge(ma._m, mb._m, backend))
    t = d["transform"]
    return Alignment(
        accepted=d["accepted"],
        reason=d.get("reason"),
        theta_deg=t["theta_deg"],
        tx=t["tx"],
        ty=t["ty"],
        score=d["score"],
        overlap=d["overlap"],
        b_scale=d["b_scale"],
        world=_world(d.get("world")),
        features=d["features"],
    )


TransformLike = Union[Alignment, Tuple[float, float, float]]


def _transform(alignment: TransformLike, force: bool) -> Tuple[float, float, float]:
    if isinstance(alignment, Alignment):
        if not alignment.accepted and not force:
            raise ValueError(
                f"not merged: {alignment.reason or 'not confident'} (force=True composes anyway)"
            )
        return alignment.transform
    theta, tx, ty = (float(v) for v in alignment)
    return (theta, tx, ty)


def compose(a: Any, b: Any, alignment: TransformLike, *, force: bool = False) -> Map:
    """The merged map of ``a`` and ``b`` in A's frame (georeferenced as A), B placed by ``alignment``
    (an ``Alignment``, or ``(theta_deg, tx, ty)``). A declined alignment is refused (``ValueError``)
    unless ``force=True``: a wrong merge is worse than none."""
    t = _transform(alignment, force)
    return Map._wrap(_core.compose(_as_map(a)._m, _as_map(b)._m, t))


def overlay(a: Any, b: Any, alignment: TransformLike) -> np.ndarray:
    """A picture of the alignment as (height, width, 3) uint8 RGB on the merged canvas: walls of A only
    blue, of B only orange, of both black; free space of both white, of one light grey; a wall on the
    other map's free space magenta."""
    t = _transform(alignment, True)
    return _core.overlay(_as_map(a)._m, _as_map(b)._m, t)


@dataclass(frozen=True)
class Pose:
    """One input map's place: ``group`` (maps placed together) and ``theta_deg``, ``tx``, ``ty`` from its
    pixels (at the reference resolution: ``scale``) to its group's merged-map pixels; ``world`` its map
    frame's pose in the merged map's frame when georeferenced."""

    map: str
    group: int
    theta_deg: float
    tx: float
    ty: float
    world: Optional[WorldTransform]
    scale: Optional[float]
    copy_of: Optional[str]

    @property
    def matrix(self) -> np.ndarray:
        """The 3x3 matrix from the map's pixels to the merged map's."""
        return rigid_matrix(self.theta_deg, self.tx, self.ty)


class _GroupError(IndexError, ValueError):
    """A group number past the last group."""


class ManyMerge:
    """Many maps placed at once (``merge_many``). Unpacks as ``merged, poses = merge_many(maps)``:
    ``merged`` is group 0's merged map (None when no two maps could be placed together), ``poses`` one
    ``Pose`` per input map, None for a map not placed (``reasons[i]`` says why).
    ``report`` is the command line's ``--poses`` document; ``merged_map(g)`` and ``overlay(g)`` draw
    any group."""

    def __init__(self, core: Any) -> None:
        self._core = core
        #: The ``merge ... --poses`` JSON document as a dict.
        self.report: Dict[str, Any] = json.loads(core._report())
        self.poses: List[Optional[Pose]] = [
            None
            if not m["placed"]
            else Pose(
                map=m["map"],
                group=m["group"],
                theta_deg=m["transform"]["theta_deg"],
                tx=m["transform"]["tx"],
                ty=m["transform"]["ty"],
                world=_world(m.get("world")),
                scale=m.get("scale"),
                copy_of=m.get("copy_of"),
            )
            for m in self.report["maps"]
        ]
        #: Why each map is not placed (None for the placed ones).
        self.reasons: List[Optional[str]] = [
            None if m["placed"] else m.get("reason") for m in self.report["maps"]
        ]
        self._merged: Dict[int, Map] = {}

    @property
    def groups(self) -> int:
        """The number of groups."""
        return len(self.report["groups"])

    def _group(self, group: Any) -> int:
        g = _args.integer("group", group)
        if g >= self.groups:
            # Past the last group: an IndexError as a list's, and a ValueError as any bad argument's.
            raise _GroupError(f"group must be less than the {self.groups} group(s), got {g}")
        return g

    def merged_map(self, group: int = 0) -> Map:
        """Group ``group``'s merged map, in its first map's frame."""
        group = self._group(group)
        if group not in self._merged:
            self._merged[group] = Map._wrap(self._core._merged(group))
        return self._merged[group]

    def overlay(self, group: int = 0) -> np.ndarray:
        """Group ``group``'s picture, each map's walls in its own colour, (height, width, 3) uint8."""
        return self._core._overlay(self._group(group))

    @property
    def merged(self) -> Optional[Map]:
        """Group 0's merged map, or None when nothing was placed together."""
        return self.merged_map(0) if self.groups else None

    def __iter__(self) -> Iterator[Any]:
        return iter((self.merged, self.poses))

    def __reduce__(self) -> Any:
        # Pickled (a process pool's result) as the report, the maps as placed, the groups and poses:
        # what its merged maps and pictures are drawn from.
        report, maps, groups, poses = self._core._parts()
        return (_unpickle_many, (report, [Map._wrap(m) for m in maps], groups, poses))

    def __repr__(self) -> str:
        placed = sum(p is not None for p in self.poses)
        return f"ManyMerge({placed} of {len(self.poses)} maps placed in {self.groups} group(s))"


def _unpickle_many(report: str, maps: List[Map], groups: List[List[int]], poses: List[Any]) -> ManyMerge:
    return ManyMerge(_core.ManyMerge._from_parts(report, [m._m for m in maps], groups, poses))


class MergeCache:
    """What one ``merge_many`` keeps for the next: each map's preparation and each pair's alignment,
    recognised by the maps' pixels. Placing the same robots again after one map changed prepares only
    that map and aligns only its pairs; the result is the one a call without the cache gives. It keeps
    only what the last call used, so its memory is about one call's. Safe to share between threads
    (calls that share it take turns)."""

    def __init__(self) -> None:
        self._core = _core.MergeCache()

    @property
    def last_use(self) -> Dict[str, int]:
        """How much of the last call came from the cache: maps reused and prepared, pairs reused and
        aligned."""
        m_reused, m_prepared, p_reused, p_aligned = self._core._last_use()
        return {"maps_reused": m_reused, "maps_prepared": m_prepared,
                "pairs_reused": p_reused, "pairs_aligned": p_aligned}

    def __repr__(self) -> str:
        return f"MergeCache(last use: {self.last_use})"


def merge_many(
    maps: Sequence[Any],
    *,
    names: Optional[Sequence[str]] = None,
    backend: str = "cpu",
    cache: Optional[MergeCache] = None,
    partners: int = 3,
    executor: Any = None,
) -> ManyMerge:
    """Places every map at once (``Map`` objects or paths): groups of maps of one place, each map's pose
    in its group's merged map, merges no single pair would trust confirmed around cycles and accepted
    ones that cycles contradict dropped. ``names`` label the maps in the report (default: their source
    files, else ``map0``, ``map1``, ...). A ``cache`` (``MergeCache``) given to successive calls redoes
    only what changed between them. In a set of more than 12 maps each map is aligned first with only its
    ``partners`` most similar maps (by the layout of their corners), then with the maps that close cycles
    and may join groups; ``partners=0`` aligns every pair. An ``executor``
    (``ogm_corners.distributed.RayExecutor()``) prepares the maps and aligns the pairs elsewhere, with the
    same result to the bit; it takes no ``cache``."""
    partners = _args.integer("partners", partners, 0, _core.MAX_PARTNERS)
    if cache is not None and not isinstance(cache, MergeCache):
        raise TypeError(f"cache must be a MergeCache, got {type(cache).__name__}")
    ms = [_as_map(m) for m in _args.sequence("maps", maps)]
    names = [m.source or f"map{i}" for i, m in enumerate(ms)] if names is None else _args.names(names)
    if executor is not None:
        if cache is not None:
            raise ValueError("an executor takes no cache: each run's work is done by the executor")
        for method in ("prepare", "align"):
            if not callable(getattr(executor, method, None)):
                raise TypeError(
                    f"executor must have prepare() and align() (see ogm_corners.distributed); "
                    f"{type(executor).__name__} has no {method}()"
                )
        return ManyMerge(
            _core.merge_many_on([m._m for m in ms], names, executor, backend, partners)
        )
    core_cache = cache._core if cache is not None else None
    return ManyMerge(
        _core.merge_many([m._m for m in ms], names, backend, core_cache, partners)
    )
