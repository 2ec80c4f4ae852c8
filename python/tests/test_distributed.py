"""Many maps merged with the work done by an executor (ogm_corners.distributed): the result is the local
run's to the bit, through the in-process reference executor and through Ray tasks on a local Ray
instance (2 CPUs); an executor's failures and foreign bytes are clear errors."""

import os

import pytest

import ogm_corners as oc
from ogm_corners import distributed as dist


def _fleet():
    """Two offices of 7 robot maps each: 14 maps, over the 12 that align every pair (screened)."""
    maps = []
    for seed in (3, 4):
        src = oc.synthetic.office(640, 480, seed=seed)
        maps += [m for m, _ in oc.synthetic.robot_maps(src, 7, seed=seed)]
    return maps


@pytest.fixture(scope="module")
def fleet():
    maps = _fleet()
    return maps, oc.merge_many(maps)


def _same(a, b):
    ra, rb = dict(a.report), dict(b.report)
    ra.pop("seconds")
    rb.pop("seconds")
    assert ra == rb
    assert ra["alignments"], "the records are compared too"


def test_the_reference_executor_gives_the_local_run_to_the_bit(fleet):
    maps, local = fleet
    placed = sum(m["placed"] for m in local.report["maps"])
    assert local.groups == 2 and placed >= 12, local.report["maps"]
    assert local.report["pairs_screened_out"] > 0
    _same(local, oc.merge_many(maps, executor=dist.SerialExecutor()))
    # Every pair too (no signatures asked for).
    _same(
        oc.merge_many(maps[:5], partners=0),
        oc.merge_many(maps[:5], partners=0, executor=dist.SerialExecutor()),
    )


def test_ray_tasks_give_the_local_run_to_the_bit(fleet):
    try:
        import ray
    except ImportError:
        if os.environ.get("CI") == "true":
            pytest.fail("Ray is not installed (pip install ray): the distributed engine is untested")
        pytest.skip("SKIPPED: Ray is not installed (pip install ray)")
    maps, local = fleet
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        executor = dist.RayExecutor()
        _same(local, oc.merge_many(maps, executor=executor))
        # Each map was prepared once, its whole preparation left in the object store.
        assert sorted(executor._whole) == list(range(len(maps)))
        assert all(isinstance(r, ray.ObjectRef) for r in executor._whole.values())
    finally:
        ray.shutdown()


class _Raises(dist.SerialExecutor):
    def align(self, pairs, options):
        raise ConnectionError("the cluster went away")


class _Short(dist.SerialExecutor):
    def align(self, pairs, options):
        return super().align(pairs, options)[:-1]


def test_an_executors_failures_are_clear_errors():
    maps = _fleet()[:4]
    with pytest.raises(ConnectionError, match="the cluster went away"):
        oc.merge_many(maps, executor=_Raises())
    with pytest.raises(ValueError, match="aligned 5 pairs of 6"):
        oc.merge_many(maps, executor=_Short())
    with pytest.raises(TypeError, match="has no prepare"):
        oc.merge_many(maps, executor=object())
    with pytest.raises(ValueError, match="no cache"):
        oc.merge_many(maps, executor=dist.SerialExecutor(), cache=oc.MergeCache())


def test_foreign_or_damaged_bytes_and_other_versions_are_refused():
    m = _fleet()[0]
    whole, part, sig = dist.prepare_map(m.pixels, m.thresholds, True)
    assert sig is not None and len(part) * 2 < len(whole)  # 3 flag bytes a pixel of about 12
    with pytest.raises(ValueError, match="install the same ogm-corners version"):
        dist.align_pair(whole, whole, "0.0.0 0000000000000000")
    # The run's options id, as a run hands it to the executor.
    seen = {}

    class Spy(dist.SerialExecutor):
        def align(self, pairs, options):
            seen["options"] = options
            return super().align(pairs, options)

    oc.merge_many(_fleet()[:2], executor=Spy())
    options = seen["options"]
    assert '"accepted"' in dist.align_pair(whole, whole, options)
    damaged = bytearray(whole)
    damaged[len(damaged) // 2] ^= 1
    with pytest.raises(ValueError, match="checksum"):
        dist.align_pair(bytes(damaged), whole, options)
    with pytest.raises(ValueError, match="placement form"):
        dist.align_pair(part, whole, options)
    with pytest.raises(ValueError, match="not a map's preparation"):
        dist.align_pair(sig, whole, options)


def test_the_synthetic_fleet_is_merge_evals():
    names, maps = oc.synthetic.fleet(6, buildings=2, seed=1)
    assert names == [f"o{k}-part-{i:02}" for k in (0, 1) for i in range(3)]
    assert len(maps) == 6 and all(m.width > 100 for m in maps)
    with pytest.raises(ValueError, match="buildings"):
        oc.synthetic.fleet(6, buildings=0)
