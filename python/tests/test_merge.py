"""Merging from Python: the truth on synthetic robot maps, the CLI's verdicts on real pairs, refusals."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import ogm_corners as oc

from conftest import run_cli


def wrap(deg: float) -> float:
    return (deg + 180.0) % 360.0 - 180.0


@pytest.fixture(scope="module")
def robots():
    src = oc.synthetic.office(800, 600, seed=2)
    return oc.synthetic.robot_maps(src, 3, seed=5)


def true_b_to_a(pa, pb):
    """B's pixels to A's from both maps' poses into the source (theta_deg, tx, ty)."""
    return np.linalg.inv(oc.rigid_matrix(*pa)) @ oc.rigid_matrix(*pb)


def test_a_pair_merges_to_the_truth(robots):
    (a, pa), (b, pb) = robots[0], robots[1]
    al = oc.merge(a, b)
    assert al.accepted and al.reason is None
    truth = true_b_to_a(pa, pb)
    assert abs(wrap(al.theta_deg - math.degrees(math.atan2(truth[1, 0], truth[0, 0])))) < 1.0
    # B's centre lands within 3 px of where the truth puts it.
    c = np.array([b.width / 2, b.height / 2, 1.0])
    assert np.linalg.norm((al.matrix @ c - truth @ c)[:2]) < 3.0
    # The world form: both maps at origin 0, so it is the pixel transform in metres, y up.
    assert al.world is not None and al.b_scale == 1.0
    assert al.world.yaw == pytest.approx(-al.theta, abs=1e-9)
    assert 0.0 < al.overlap <= 1.0 and al.score > 0
    merged = oc.compose(a, b, al)
    assert merged.resolution == a.resolution
    assert merged.width >= a.width and merged.height >= a.height
    pic = oc.overlay(a, b, al)
    assert pic.shape == (merged.height, merged.width, 3) and pic.dtype == np.uint8


def test_a_declined_merge_is_not_composed_unless_forced(robots):
    a = robots[0][0]
    noise = np.full((300, 300), 205, np.uint8)
    noise[100:200, 100:200] = 254
    b = oc.Map(noise)
    al = oc.merge(a, b)
    assert not al.accepted and al.reason
    with pytest.raises(ValueError, match="not merged"):
        oc.compose(a, b, al)
    assert oc.compose(a, b, al, force=True).width >= a.width


def test_resolutions_differing_are_resampled(robots):
    (a, _), (b, _) = robots[0], robots[1]
    coarse = b.with_georef(0.1)  # B said to be at 0.1 m a pixel: twice A's size once resampled
    al = oc.merge(a, coarse)
    assert al.b_scale == pytest.approx(2.0)
    oc.compose(a, coarse, al, force=True)


def test_many_maps_are_placed_consistently(robots):
    maps = [m for m, _ in robots]
    result = oc.merge_many(maps, names=["r0", "r1", "r2"])
    merged, poses = result
    assert result.groups == 1 and all(p is not None for p in poses)
    assert [p.map for p in poses] == ["r0", "r1", "r2"]
    assert merged.shape == (result.report["groups"][0]["height"], result.report["groups"][0]["width"])
    for i in (1, 2):
        truth = true_b_to_a(robots[0][1], robots[i][1])
        rel = np.linalg.inv(poses[0].matrix) @ poses[i].matrix
        turn = math.degrees(math.atan2(rel[1, 0], rel[0, 0]) - math.atan2(truth[1, 0], truth[0, 0]))
        assert abs(wrap(turn)) < 1.0
    assert result.overlay().shape == (merged.height, merged.width, 3)
    with pytest.raises(IndexError):
        result.merged_map(1)


def test_a_cache_redoes_only_the_changed_map_and_gives_the_same_report(robots):
    maps = [m for m, _ in robots]
    names = ["r0", "r1", "r2"]
    cache = oc.MergeCache()
    first = oc.merge_many(maps, names=names, cache=cache)
    assert cache.last_use == {"maps_reused": 0, "maps_prepared": 3, "pairs_reused": 0, "pairs_aligned": 3}
    again = oc.merge_many(maps, names=names, cache=cache)
    assert cache.last_use == {"maps_reused": 3, "maps_prepared": 0, "pairs_reused": 3, "pairs_aligned": 0}
    assert again.report["maps"] == first.report["maps"]
    # One pixel of r1 turned to wall: r1 prepared again and its two pairs aligned again.
    px = maps[1].pixels.copy()
    y, x = np.argwhere(px > 250)[0]
    px[y, x] = 0
    maps[1] = oc.Map(px)
    changed = oc.merge_many(maps, names=names, cache=cache)
    assert cache.last_use == {"maps_reused": 2, "maps_prepared": 1, "pairs_reused": 1, "pairs_aligned": 2}
    assert changed.report["maps"] == oc.merge_many(maps, names=names).report["maps"]
    with pytest.raises(TypeError, match="MergeCache"):
        oc.merge_many(maps, cache={})


def test_partners_is_checked_and_small_sets_align_every_pair(robots):
    maps = [m for m, _ in robots]
    names = ["r0", "r1", "r2"]
    screened = oc.merge_many(maps, names=names)
    every = oc.merge_many(maps, names=names, partners=0)
    # Three maps are under the size a pre-screen starts at: every pair aligned either way.
    assert screened.report["pairs_aligned"] == every.report["pairs_aligned"] == 3
    assert screened.report["pairs_screened_out"] == 0
    assert screened.report["maps"] == every.report["maps"]
    with pytest.raises(ValueError, match="partners"):
        oc.merge_many(maps, partners=-1)
    with pytest.raises(ValueError, match="partners"):
        oc.merge_many(maps, partners=5000)
    with pytest.raises(TypeError, match="partners"):
        oc.merge_many(maps, partners="3")
    with pytest.raises(TypeError, match="partners"):
        oc.merge_many(maps, partners=True)


def test_merge_many_needs_two_maps(robots):
    with pytest.raises(ValueError, match="at least two maps"):
        oc.merge_many([robots[0][0]])


def test_same_verdicts_as_the_cli_on_real_pairs(cli, merge_pairs):
    pairs = json.loads((merge_pairs / "pairs.json").read_text())
    checks = [pairs["pairs"][0], pairs["negatives"][0]]
    for p in checks:
        a, b = (merge_pairs / "maps" / f"{p[k]}.png" for k in ("dst", "src"))
        r = run_cli(cli, "merge", a, b, "--format", "json")
        assert r.returncode in (0, 3), r.stderr
        want = json.loads(r.stdout)
        got = oc.merge(a, b)
        assert got.accepted == want["accepted"] and got.reason == want.get("reason")
        assert (got.theta_deg, got.tx, got.ty) == (
            want["transform"]["theta_deg"], want["transform"]["tx"], want["transform"]["ty"])
        assert got.score == want["score"] and got.features == want["features"]
