"""Synthetic maps with exact truth, for trying the package without data and for tests: the seeded office
map of ``ogm-corners demo``, and overlapping robot maps cut from a map, each turned and shifted."""

from __future__ import annotations

from typing import List, Tuple

from . import _args, _core
from ._map import Map


def office(width: int = 1024, height: int = 768, seed: int = 1, resolution: float = 0.05) -> Map:
    """The synthetic office map of ``ogm-corners demo`` (rooms, doors, furniture, unknown outside),
    georeferenced at ``resolution`` metres a pixel with origin 0."""
    width, height = _args.unsigned("width", width, 32), _args.unsigned("height", height, 32)
    return Map._wrap(_core.synthetic_office(width, height, _args.unsigned("seed", seed, 64), resolution))


def robot_maps(
    source: Map, n: int, *, noise: float = 0.0, seed: int = 1
) -> List[Tuple[Map, Tuple[float, float, float]]]:
    """``n`` overlapping maps cut from ``source`` as ``n`` robots would have mapped it: windows about 45%
    shared with their neighbours, each turned by a random angle and shifted, free cells speckled with
    probability ``noise``. Each comes with its exact pose (theta_deg, tx, ty): its pixels to the
    source's. They keep the source's resolution, with origin 0."""
    n, seed = _args.integer("n", n, 0, 64), _args.unsigned("seed", seed, 64)
    return [
        (Map._wrap(m), pose)
        for m, pose in _core.synthetic_robot_maps(source._m, n, noise, seed)
    ]


def fleet(n: int, buildings: int = 4, seed: int = 1) -> Tuple[List[str], List[Map]]:
    """The synthetic fleet of ``ogm-corners merge-eval --global --set-size n --buildings b``: ``n`` robot
    maps cut from ``buildings`` synthetic offices (a share each, mixed), with their names
    (``oK-part-NN``: office K). For trying large merges (``merge_many``) without data."""
    n, buildings = _args.integer("n", n, 1, 2000), _args.integer("buildings", buildings, 1, 64)
    pairs = _core.synthetic_fleet(n, buildings, _args.unsigned("seed", seed, 64))
    return [name for name, _ in pairs], [Map._wrap(m) for _, m in pairs]
