"""Many maps merged with the work spread over a cluster: ``merge_many(maps, executor=RayExecutor())``.

The run itself (which pairs to align, the placement) stays in this process; what takes the time, each
map's preparation and each chosen pair's alignment, is done by an *executor*. Each map is prepared once,
on some worker, and its preparation stays in the cluster (Ray's object store): every pair task that needs
it is handed it by reference, not sent again from here. This process receives only the small part of
each preparation that the placement reads (about 3 bytes a pixel) and each pair's record (a few hundred
bytes). The result is the local run's, bit for bit: preparation and alignment are pure functions of the
pixels and the options, and what comes back is exact (floats as their bits).

    import ray, ogm_corners as oc
    ray.init(address="auto")          # an existing cluster; ray.init() starts one on this machine
    many = oc.merge_many(maps, executor=oc.distributed.RayExecutor())

Ray is optional (``pip install 'ogm-corners[ray]'``); without an executor the local threads are used.

An executor is any object with the two methods of :class:`SerialExecutor` (the reference, in this
process): another engine (Dask, a process pool) fits the same way.
"""

from __future__ import annotations

from typing import Any, Iterable, List, Optional, Tuple

from . import _core

__all__ = ["Executor", "RayExecutor", "SerialExecutor", "prepare_map", "align_pair"]


def prepare_map(pixels: Any, thresholds: Tuple[bool, float, float], signature: bool):
    """A worker's task: one map's preparation as bytes, (whole, placement part, signature or None)."""
    negate, occupied, free = thresholds
    return _core._prepare_encoded(pixels, negate, occupied, free, signature)


def align_pair(a: bytes, b: bytes, options: str) -> str:
    """A worker's task: map ``b`` aligned onto map ``a`` (whole preparations), the pair's record as JSON.
    ``options`` names the run's alignment options; a worker of another version refuses."""
    return _core._align_encoded(a, b, options)


class Executor:
    """What ``merge_many`` asks of an executor (the protocol; see :class:`SerialExecutor`)."""

    def prepare(
        self, maps: List[Tuple[int, Any]], signatures: bool
    ) -> Iterable[Tuple[bytes, Optional[bytes]]]:
        """Prepares each ``(index, Map)``: keeps its whole preparation for :meth:`align` under
        ``index``, and returns (its placement part, its signature when ``signatures``), in order: a list,
        or an iterator that hands them over as they come (each is decoded and let go before the next)."""
        raise NotImplementedError

    def align(self, pairs: List[Tuple[int, int]], options: str) -> List[str]:
        """Aligns each ``(a, b)`` (map ``b`` onto map ``a``, by the indices :meth:`prepare` was given):
        :func:`align_pair` of their whole preparations, in order."""
        raise NotImplementedError


class SerialExecutor(Executor):
    """The reference executor: the work done one item at a time in this process, through the same bytes
    a distributed executor moves (so a run through it checks the encodings; it is not faster)."""

    def __init__(self) -> None:
        self._whole: dict = {}

    def prepare(self, maps, signatures):
        out = []
        for index, m in maps:
            whole, part, sig = prepare_map(m.pixels, m.thresholds, signatures)
            self._whole[index] = whole
            out.append((part, sig))
        return out

    def align(self, pairs, options):
        return [align_pair(self._whole[a], self._whole[b], options) for a, b in pairs]


class RayExecutor(Executor):
    """Each map prepared by a Ray task, its whole preparation left in Ray's object store, and each pair
    aligned by a Ray task handed the two preparations by reference. Uses the Ray cluster this process is
    connected to (``ray.init(...)`` first; without it Ray starts one on this machine). ``num_cpus``:
    the CPUs Ray reserves for each task (1: one task a core; an alignment uses one core)."""

    def __init__(self, num_cpus: float = 1) -> None:
        try:
            import ray
        except ImportError as e:  # pragma: no cover - the message is the point
            raise ImportError(
                "RayExecutor needs Ray: pip install 'ogm-corners[ray]' (or pip install ray)"
            ) from e
        self._ray = ray
        self._prepare = ray.remote(num_cpus=num_cpus, num_returns=3)(prepare_map)
        self._align = ray.remote(num_cpus=num_cpus)(align_pair)
        self._whole: dict = {}

    def prepare(self, maps, signatures):
        ray = self._ray
        parts, sigs = [], []
        for index, m in maps:
            whole, part, sig = self._prepare.remote(m.pixels, m.thresholds, signatures)
            self._whole[index] = whole
            parts.append(part)
            sigs.append(sig)
        return self._fetched(parts, sigs)

    def _fetched(self, parts, sigs):
        # A few at a time, each reference let go once fetched: the caller decodes each part as it comes,
        # so neither this process nor the object store holds every map's part at once (at 1,000 maps of
        # 1500 px the parts are about 7 GB).
        step = 16
        for i in range(0, len(parts), step):
            got = zip(self._ray.get(parts[i : i + step]), self._ray.get(sigs[i : i + step]))
            parts[i : i + step] = [None] * len(parts[i : i + step])
            sigs[i : i + step] = [None] * len(sigs[i : i + step])
            yield from got

    def align(self, pairs, options):
        refs = [self._align.remote(self._whole[a], self._whole[b], options) for a, b in pairs]
        return self._ray.get(refs)
