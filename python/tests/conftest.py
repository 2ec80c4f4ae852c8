"""Shared fixtures: the command-line tool to compare with, the shared real maps, synthetic maps.

Data and tools that are missing make a test skip with a loud reason, and fail under CI=true (as the Rust
tests do): a check that silently did not run is a defect.
"""

from __future__ import annotations

import os
import pathlib
import subprocess

import pytest

import ogm_corners as oc

ROOT = pathlib.Path(__file__).resolve().parents[2]
CI = os.environ.get("CI") == "true"


def missing(why: str) -> None:
    """Fails under CI=true, skips loudly otherwise."""
    if CI:
        pytest.fail(f"{why} (required under CI=true)")
    pytest.skip(f"SKIPPED: {why}")


def shared_dir(var: str, name: str) -> pathlib.Path | None:
    p = pathlib.Path(os.environ.get(var) or ROOT.parent / "shared" / name)
    return p if p.is_dir() else None


@pytest.fixture(scope="session")
def cli() -> pathlib.Path:
    """The ogm-corners binary (`$OGM_CORNERS_BIN`, else target/debug or target/release)."""
    candidates = [os.environ.get("OGM_CORNERS_BIN")] + [
        str(ROOT / "target" / p / "ogm-corners") for p in ("debug", "release")
    ]
    for c in candidates:
        if c and os.access(c, os.X_OK):
            return pathlib.Path(c)
    missing("the ogm-corners binary was not found (cargo build, or set OGM_CORNERS_BIN)")
    raise AssertionError("unreachable")


def run_cli(cli: pathlib.Path, *args: object) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(cli), *map(str, args)], capture_output=True, text=True, timeout=600
    )


@pytest.fixture(scope="session")
def shared_maps() -> list[pathlib.Path]:
    """Every map yaml of ../shared/maps (`$OGM_MAPS_DIR`)."""
    d = shared_dir("OGM_MAPS_DIR", "maps")
    if d is None:
        missing("../shared/maps not found: the real-map checks did NOT run")
    maps = sorted(d.rglob("*.yaml"))
    if not maps:
        missing(f"no map yaml under {d}")
    return maps


@pytest.fixture(scope="session")
def merge_pairs() -> pathlib.Path:
    """The merge-pairs data set (`$OGM_MERGE_PAIRS_DIR`, else ../shared/merge-pairs)."""
    d = shared_dir("OGM_MERGE_PAIRS_DIR", "merge-pairs")
    if d is None or not (d / "pairs.json").is_file():
        missing("../shared/merge-pairs not found: the real merge checks did NOT run")
    return d


@pytest.fixture(scope="session")
def office() -> oc.Map:
    return oc.synthetic.office(640, 480, seed=7)


@pytest.fixture(scope="session")
def office_files(tmp_path_factory: pytest.TempPathFactory, office: oc.Map) -> pathlib.Path:
    """The synthetic office saved as a ROS map (yaml + pgm)."""
    p = tmp_path_factory.mktemp("office") / "office.yaml"
    office.save(p)
    return p
