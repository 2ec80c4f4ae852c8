"""One large merge timed: the synthetic fleet of ``merge-eval --global`` (N maps of several offices) placed
by ``merge_many`` on this process's threads or on a local Ray instance, as one JSON line.

    python distributed_scale.py --size 200 --engine local
    python distributed_scale.py --size 200 --engine ray --cpus 2

The line: maps, engine, CPUs, seconds (the merge alone; Ray's start-up apart), pairs aligned and left
out, maps placed, groups, this process's peak memory (MB), the bytes the preparations take in Ray's
object store, and a digest of the report (every pose and pair record; the time aside), which is the same
whichever engine ran it. ``scripts/figures.py ray-scale`` runs it for the README's curve.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import resource
import sys
import time

import ogm_corners as oc
from ogm_corners import distributed


def digest(report: dict) -> str:
    r = dict(report)
    r.pop("seconds", None)
    return hashlib.sha256(json.dumps(r, sort_keys=True).encode()).hexdigest()[:16]


class CountingRay(distributed.RayExecutor):
    """The Ray executor, also keeping the size of each whole preparation it leaves in the store."""

    def __init__(self) -> None:
        super().__init__()
        import ray

        def sized(pixels, thresholds, signature):
            whole, part, sig = distributed.prepare_map(pixels, thresholds, signature)
            return whole, part, sig, len(whole)

        self._prepare = ray.remote(num_cpus=1, num_returns=4)(sized)
        self.stored = 0

    def prepare(self, maps, signatures):
        ray = self._ray
        parts, sigs, sizes = [], [], []
        for index, m in maps:
            whole, part, sig, size = self._prepare.remote(m.pixels, m.thresholds, signatures)
            self._whole[index] = whole
            parts.append(part)
            sigs.append(sig)
            sizes.append(size)
        self.stored += sum(ray.get(sizes))
        return self._fetched(parts, sigs)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, required=True, help="maps in the fleet")
    ap.add_argument("--buildings", type=int, default=4)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--engine", choices=["local", "ray"], default="local")
    ap.add_argument("--cpus", type=int, default=2, help="Ray: the CPUs of the local instance")
    ap.add_argument("--partners", type=int, default=3)
    a = ap.parse_args()
    names, maps = oc.synthetic.fleet(a.size, a.buildings, a.seed)
    executor = None
    if a.engine == "ray":
        import ray

        ray.init(num_cpus=a.cpus, include_dashboard=False, log_to_driver=False)
        executor = CountingRay()
    t = time.perf_counter()
    many = oc.merge_many(maps, names=names, partners=a.partners, executor=executor)
    seconds = time.perf_counter() - t
    rep = many.report
    line = {
        "maps": a.size,
        "buildings": a.buildings,
        "engine": a.engine,
        "cpus": a.cpus if a.engine == "ray" else None,
        "seconds": round(seconds, 2),
        "pairs_aligned": rep["pairs_aligned"],
        "pairs_screened_out": rep["pairs_screened_out"],
        "placed": sum(m["placed"] for m in rep["maps"]),
        "groups": len(rep["groups"]),
        "peak_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024),
        "object_store_mb": round(executor.stored / 1e6) if executor is not None else None,
        "digest": digest(rep),
    }
    print(json.dumps(line))
    return 0


if __name__ == "__main__":
    sys.exit(main())
