"""Simulated exploration for the map_merge node's tests and benchmark: a finished map turned into the
growing maps a robot's SLAM would have published while it explored.

A robot starts in free space and explores outwards along the free space (not through walls): at share
``s`` of its exploration it knows every cell within ``s`` of its farthest geodesic distance from the start
(distances through free cells, walls seen from the free cells next to them). Its grid is the box of what it
knows, so the grid grows and its origin moves as a SLAM map's does (slam_toolbox, gmapping), while its map
frame stays put. At ``s = 1`` it knows the whole map.
"""

from __future__ import annotations

from typing import Optional, Tuple

import numpy as np

from .live import Pose2

#: Cells per step of the geodesic distance (it is measured on a grid this much coarser).
STEP = 4


def geodesic(cells: np.ndarray, start: Optional[Tuple[int, int]] = None, step: int = STEP) -> np.ndarray:
    """Each cell's distance through free space from ``start`` (row, column; default: the free cell nearest
    the free cells' centroid), in cells, to ``step`` cells; inf where free space does not reach."""
    h, w = cells.shape
    hc, wc = -(-h // step), -(-w // step)
    pad = np.full((hc * step, wc * step), -1, np.int8)
    pad[:h, :w] = cells
    blocks = pad.reshape(hc, step, wc, step)
    free = ((blocks >= 0) & (blocks <= 25)).any(axis=(1, 3)) & ~(blocks >= 65).any(axis=(1, 3))
    if not free.any():
        return np.full((h, w), np.inf, np.float32)
    fy, fx = np.nonzero(free)
    if start is None:
        cy, cx = fy.mean(), fx.mean()
        k = int(np.argmin((fy - cy) ** 2 + (fx - cx) ** 2))
        sy, sx = int(fy[k]), int(fx[k])
    else:
        sy, sx = start[0] // step, start[1] // step
    dist = np.full((hc, wc), np.inf, np.float32)
    reached = np.zeros((hc, wc), bool)
    reached[sy, sx] = True
    frontier = reached.copy()
    d = 0
    # Breadth first through free blocks, the whole frontier a step at a time (8-connected).
    while frontier.any():
        dist[frontier] = d
        grown = frontier.copy()
        grown[1:] |= frontier[:-1]
        grown[:-1] |= frontier[1:]
        grown[:, 1:] |= grown[:, :-1].copy()
        grown[:, :-1] |= grown[:, 1:].copy()
        frontier = grown & free & ~reached
        reached |= frontier
        d += 1
    # Walls and unknown-free borders next to reached free space are seen from it: one block of reach.
    seen = dist.copy()
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            shifted = np.full_like(dist, np.inf)
            shifted[max(dy, 0) : hc + min(dy, 0), max(dx, 0) : wc + min(dx, 0)] = dist[
                max(-dy, 0) : hc + min(-dy, 0), max(-dx, 0) : wc + min(-dx, 0)
            ]
            seen = np.minimum(seen, shifted + 1)
    return np.repeat(np.repeat(seen * step, step, axis=0), step, axis=1)[:h, :w]


def explored(cells: np.ndarray, distance: np.ndarray, share: float) -> np.ndarray:
    """What the robot knows at ``share`` of its exploration: the known cells within that share of the
    farthest reachable distance (all of them at share 1)."""
    if share >= 1.0:
        return cells.copy()
    finite = distance[np.isfinite(distance)]
    limit = share * (finite.max() if finite.size else 0.0)
    out = np.full_like(cells, -1)
    near = distance <= limit
    out[near] = cells[near]
    return out


def crop_known(cells: np.ndarray, res: float) -> Tuple[np.ndarray, Pose2]:
    """A growing SLAM map's grid: its known cells' box, the origin moved to the box's corner (the map
    frame is the full grid's, origin 0)."""
    rows, cols = np.nonzero(cells >= 0)
    if rows.size == 0:
        return np.full((1, 1), -1, np.int8), (0.0, 0.0, 0.0)
    r0, c0 = rows.min(), cols.min()
    return np.ascontiguousarray(cells[r0 : rows.max() + 1, c0 : cols.max() + 1]), (c0 * res, r0 * res, 0.0)


def frame_of_pixels(height: int, res: float) -> np.ndarray:
    """Pixel (column, row; row 0 at the top, centres at integers) to the map frame (metres, y up) of a map
    image of ``height`` rows whose grid has origin 0."""
    return np.array([[res, 0, 0.5 * res], [0, -res, (height - 0.5) * res], [0, 0, 1.0]])


def pair_errors(src_pose: Pose2, dst_pose: Pose2, pair: dict, heights: Tuple[int, int], res: float) -> Tuple[float, float]:
    """The placement of two maps against a ``pairs.json`` pair (shared/merge-pairs conventions): (rotation
    error in degrees, RMS in pixels over the annotated points). ``heights``: the src and dst images' rows."""
    from .live import pose_matrix

    t = (np.linalg.inv(frame_of_pixels(heights[1], res)) @ np.linalg.inv(pose_matrix(dst_pose))
         @ pose_matrix(src_pose) @ frame_of_pixels(heights[0], res))
    rot = float(np.degrees(np.arctan2(t[1, 0], t[0, 0])))
    s = np.c_[np.array(pair["src_points"]), np.ones(len(pair["src_points"]))]
    rms = float(np.sqrt(np.mean(np.sum(((s @ t.T)[:, :2] - np.array(pair["dst_points"])) ** 2, axis=1))))
    off = abs((rot - pair["theta_deg"] + 180.0) % 360.0 - 180.0)
    return off, rms
