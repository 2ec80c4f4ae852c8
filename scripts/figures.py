#!/usr/bin/env python3
"""The documentation's measured figures, regenerated (scripts/figures.py --help).

"""

import argparse
import datetime
import json
import os
import platform
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

USAGE = """Regenerates the measured figures of the documentation chapters, so that every one is measured on the
revision that states it, on a named machine.

    scripts/figures.py                 list the figures and where they go
    scripts/figures.py NAME... | all   measure them and print each block (Markdown) on stdout
    scripts/figures.py --write NAME... | all
                                       also put each block into its chapter, between the lines
                                       <!-- figure:NAME --> and <!-- /figure:NAME --> (temp file, rename)

Each block starts with a line naming the script, the date, the commit, the machine, the commands it ran
and how long they took; what follows is the tool's own output (its Markdown tables), or a table this script
builds from the tool's JSON (means over maps, sums, ratios). The prose around a block is written by hand
and must agree with it: after a run, read the chapter again.

The figures (about 25 minutes in all on the project's 2-core VM, most of it `streamed`, `global`,
`ablation`, `partial`, `compare` and `python`):
{figures}

Needs the shared data beside the project (../shared/maps, ../shared/merge-pairs, ../shared/maps-more); exits 2
without it.
Builds the release binary (cargo build --release --locked) unless OGM_BIN names one. Timings on the
project's VM vary by 20% or more; run on a quiet machine. Not part of CI.
"""

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SHARED = os.path.normpath(os.path.join(ROOT, "..", "shared"))
PAIRS = os.path.join(SHARED, "merge-pairs", "pairs.json")
CORNERS = os.path.join(SHARED, "merge-pairs", "corners.json")
PAIR_MAPS = os.path.join(SHARED, "merge-pairs", "maps")
MAPS = os.path.join(SHARED, "maps")
WRITE = False  # --write: the chapters, and the pictures a figure draws (docs/results), are rewritten
DETECTORS = ["ogm", "ogm-robust", "harris", "shi-tomasi", "trajkovic"]


def fail(msg, code=1):
    print(f"figures.py: {msg}", file=sys.stderr)
    sys.exit(code)


def shown(arg):
    """An argument as the chapters show it: the shared data as ../shared, the work folder as OUT."""
    s = str(arg).replace(SHARED, "../shared")
    return s


def machine():
    cpu, mem = "unknown CPU", 0
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
        for line in open("/proc/meminfo"):
            if line.startswith("MemTotal"):
                mem = int(line.split()[1]) / 2**20
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, {mem:.0f} GiB, {platform.system()}"


def commit():
    try:
        c = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                           text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--", ".",
                                ":!*.md", ":!docs/results"], cwd=ROOT, capture_output=True,
                               text=True).stdout.strip()
        return c + (" with uncommitted changes" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def shared_map_files():
    """The 26 shared maps as the chapters list them: every yaml, every png, the stage world's pgm files."""
    out = []
    for d, _, files in os.walk(MAPS):
        for f in files:
            if f.endswith((".yaml", ".png")):
                out.append(os.path.join(d, f))
    stage = os.path.join(MAPS, "navigation_tutorials", "navigation_stage", "stage_config", "maps")
    if os.path.isdir(stage):
        out += [os.path.join(stage, f) for f in os.listdir(stage) if f.endswith(".pgm")]
    return sorted(out)


class Runner:
    """Runs commands once each (a figure that needs another's run reuses it), timing them."""

    def __init__(self, binary, work):
        self.bin, self.work, self.cache = binary, work, {}
        self.log = []  # (command as shown, seconds) of the current figure

    def run(self, argv, env=None, shown_argv=None):
        key = (tuple(argv), tuple(sorted((env or {}).items())))
        text = " ".join(shlex.quote(shown(a).replace(self.work, "OUT")) for a in (shown_argv or argv))
        # The 26 shared maps are named MAPS in the stamp, not one by one.
        maps = " ".join(shlex.quote(shown(m)) for m in shared_map_files())
        text = text.replace(maps, "MAPS")
        if key not in self.cache:
            print(f"figures.py: running {text}", file=sys.stderr)
            t = time.time()
            p = subprocess.run(argv, capture_output=True, text=True, cwd=ROOT,
                               env={**os.environ, **(env or {})})
            secs = time.time() - t
            if p.returncode != 0:
                sys.stderr.write(p.stderr[-3000:])
                fail(f"failed (exit {p.returncode}): {text}")
            self.cache[key] = (p.stdout, secs)
        out, secs = self.cache[key]
        self.log.append((text, secs))
        return out

    def tool(self, *args):
        """The tool's standard output."""
        return self.run([self.bin, *map(str, args)], shown_argv=["ogm-corners", *map(str, args)])

    def json(self, *args):
        return json.loads(self.tool(*args, "--format", "json"))


def pct(x):
    return "n/a" if x is None else f"{100 * x:.1f}%"


def table(header, rows):
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(lines)


# ---- The detectors ----

def annotation_runs(r):
    base = ["eval", "--backend", "cpu", "--annotations", CORNERS, PAIR_MAPS]
    return r.json(*base), r.json(*base, "--min-strength", "1")


def fig_annotations(r):
    shipped, s1 = annotation_runs(r)
    names = {"ogm": "ogm (the paper's)", "ogm-unknown-as-occupied": "ogm, unknown as occupied",
             "ogm-robust": "**ogm-robust**"}
    rows = []

    def row(rec, name):
        m = rec["marked"]
        f = lambda k: "n/a" if rec[k] is None else f"{100 * rec[k] / m:.1f}%"
        return [name, rec["keypoints"], f("hits_5"), f("hits_10"), f("hits_5_budget_1x"),
                f("hits_5_budget_3x"), f("hits_10_budget_1x"), f("hits_10_budget_3x")]

    pooled = [x for x in shipped if x["map"] == "all"]
    for rec in pooled:
        rows.append(row(rec, names.get(rec["detector"], rec["detector"])))
        if rec["detector"] == "ogm-robust":
            rows.append(row(next(x for x in s1 if x["map"] == "all" and x["detector"] == "ogm-robust"),
                            "ogm-robust `--min-strength 1`"))
    maps = len({x["map"] for x in shipped if x["map"] != "all"})
    head = f"Pooled over {maps} maps, {pooled[0]['marked']} marked points:\n\n"
    return head + table(["detector", "keypoints", "within 5 px", "within 10 px", "5 px, 1x budget",
                         "5 px, 3x budget", "10 px, 1x budget", "10 px, 3x budget"], rows)


def repeatability_means(records):
    """{(condition, level): {detector: mean repeatability over the maps}}."""
    acc = {}
    for x in records:
        if x["repeatability"] is None:  # no keypoint in the region both see: nothing to repeat
            continue
        acc.setdefault((x["condition"], x["level"]), {}).setdefault(x["detector"], []).append(x["repeatability"])
    return {k: {d: statistics.fmean(v) for d, v in m.items()} for k, m in acc.items()}


def repeatability_runs(r):
    maps = shared_map_files()
    base = ["eval", *maps, "--backend", "cpu", "--trials", "2"]
    return r.json(*base, "--plot", os.path.join(r.work, "plots")), r.json(*base, "--min-strength", "1")


def bench_detectors(r):
    return r.json("bench", "--size", "4096x4096", "--detector", "all", "--backend", "cpu", "--repeat", "10")


def end_to_end(bench, detector, backend="cpu", size=None):
    for x in bench["records"]:
        if (x["detector"] == detector and x["backend"] == backend and x["stage"] == "end_to_end"
                and (size is None or x["width"] == size)):
            return x
    return None


def fig_robust_summary(r):
    shipped, s1 = annotation_runs(r)
    rep, rep1 = (repeatability_means(x) for x in repeatability_runs(r))
    bench = bench_detectors(r)

    def recall(recs, det, k):
        x = next(x for x in recs if x["map"] == "all" and x["detector"] == det)
        return pct(None if x[k] is None else x[k] / x["marked"])

    def per_point(recs, det):
        x = next(x for x in recs if x["map"] == "all" and x["detector"] == det)
        return f"{x['keypoints'] / x['marked']:.1f}"

    def span(means, conds, det):
        v = [m[det] for (c, _), m in means.items() if c in conds and det in m]
        lo, hi = min(v), max(v)
        return f"{100 * lo:.0f}-{100 * hi:.0f}%" if round(100 * lo) != round(100 * hi) else f"{100 * lo:.0f}%"

    def speed(det):
        x = end_to_end(bench, det)
        return f"{x['median_ms']:.1f} ms, {x['mpx_per_s']:.0f} Mpx/s"

    cols = [(shipped, rep, "ogm"), (shipped, rep, "ogm-robust"), (s1, rep1, "ogm-robust")]
    turns = ("rot90", "rot180", "rot270", "mirror")
    rows = [
        ["marked corners within 5 px, strongest 3 per marked point",
         *[recall(a, d, "hits_5_budget_3x") for a, _, d in cols], "60%"],
        ["marked corners within 10 px, strongest 3 per marked point",
         *[recall(a, d, "hits_10_budget_3x") for a, _, d in cols], "80%"],
        ["keypoints per marked point", *[per_point(a, d) for a, _, d in cols], "at most 3"],
        ["repeatability, arbitrary rotation (15-75 deg, the range of the 5 angles' means over 26 maps)",
         *[span(m, ("rotation",), d) for _, m, d in cols], "85%"],
        ["repeatability, 90/180/270-degree turns and mirroring",
         *[span(m, turns, d) for _, m, d in cols], "100%"],
        ["repeatability, two crops sharing 30/50/70% (in the map's frame; each crop's own wall direction)",
         *[span(m, ("overlap",), d) for _, m, d in cols], "100%"],
        ["CPU end to end, 4096^2 synthetic office (median of 10)", speed("ogm"), speed("ogm-robust"), "-",
         "1000 Mpx/s"],
    ]
    return table(["", "paper's OGM", "ogm-robust (default)", "ogm-robust `--min-strength 1`", "target"], rows)


# The robust detector's settings searched by leave-one-building-out: the shorter wall kept (px) and the
# largest coarse scale. The default (the fit on all three buildings) is among them.
ROBUST_DEFAULT = (12, 12)
LOBO_MIN_STRENGTH = (1, 4, 8, 12, 16, 24)
LOBO_MAX_SCALE = (8, 10, 12)


def building(map_name):
    """F5_03 -> F5: the merge-pairs maps are named by building."""
    return map_name.split("_")[0]


def lobo_fit(r, settings, flags, default, describe):
    """Fit a robust-detector setting on two buildings, report the third, for each; pooled held-out last.

    `settings` are tuples, `flags(setting)` their command-line options, `describe(setting)` their name.
    The fit maximises the two target measures equally weighted: the share of the two buildings' marked
    corners with a keypoint within 10 px (strongest 3 per marked point), plus the mean repeatability under
    arbitrary rotation on the 26 shared maps (other maps than the buildings'), among the settings with at
    most 3 keypoints per marked point on the two buildings. Returns the table and the search's summary."""
    per_setting = {}
    for st in settings:
        recs = r.json("eval", "--backend", "cpu", "--annotations", CORNERS, PAIR_MAPS, *flags(st))
        per_setting[st] = [x for x in recs if x["detector"] == "ogm-robust" and x["map"] != "all"]
    buildings = sorted({building(x["map"]) for x in next(iter(per_setting.values()))})
    maps = shared_map_files()
    rotation = {}

    def repeat(setting):
        # Computed only for settings within the keypoint budget somewhere (each run takes about 30 s).
        if setting not in rotation:
            recs = r.json("eval", *maps, "--backend", "cpu", "--trials", "1", *flags(setting))
            v = [x["repeatability"] for x in recs if x["detector"] == "ogm-robust"
                 and x["condition"] == "rotation" and x["repeatability"] is not None]
            rotation[setting] = statistics.fmean(v)
        return rotation[setting]

    keys = ("marked", "keypoints", "hits_5_budget_3x", "hits_10_budget_3x")

    def pooled(setting, keep):
        xs = [x for x in per_setting[setting] if keep(building(x["map"]))]
        return {k: sum(x[k] or 0 for x in xs) for k in keys}

    def objective(setting, keep):
        t = pooled(setting, keep)
        if t["keypoints"] > 3 * t["marked"]:
            return (False, 0.0)
        return (True, t["hits_10_budget_3x"] / t["marked"] + repeat(setting))

    rows, held, dflt_all = [], {k: 0 for k in keys}, {k: 0 for k in keys}
    for b in buildings:
        fit = max(per_setting, key=lambda st: (objective(st, lambda x: x != b), st == default))
        out, dflt = pooled(fit, lambda x: x == b), pooled(default, lambda x: x == b)
        for k in keys:
            held[k] += out[k]
            dflt_all[k] += dflt[k]
        rows.append([b, describe(fit), out["marked"],
                     pct(out["hits_5_budget_3x"] / out["marked"]), pct(out["hits_10_budget_3x"] / out["marked"]),
                     f"{out['keypoints'] / out['marked']:.1f}", pct(repeat(fit)),
                     pct(dflt["hits_5_budget_3x"] / dflt["marked"]), pct(dflt["hits_10_budget_3x"] / dflt["marked"])])
    rows.append(["**all three, held out**", "-", held["marked"],
                 f"**{pct(held['hits_5_budget_3x'] / held['marked'])}**",
                 f"**{pct(held['hits_10_budget_3x'] / held['marked'])}**",
                 f"{held['keypoints'] / held['marked']:.1f}", "-",
                 pct(dflt_all["hits_5_budget_3x"] / dflt_all["marked"]),
                 pct(dflt_all["hits_10_budget_3x"] / dflt_all["marked"])])
    every = max(per_setting, key=lambda st: (objective(st, lambda x: True), st == default))
    pooled_all = {st: pooled(st, lambda x: True) for st in settings}
    summary = (f"Fitted on all three buildings: {describe(every)} (the default is {describe(default)}). "
               "Each setting searched, pooled over the three buildings (10 px, 3x; keypoints per marked "
               "point) and its rotation repeatability (mean of 15-75 deg, 1 trial) where measured: "
               + "; ".join(f"{describe(st)}: {pct(t['hits_10_budget_3x'] / t['marked'])}, "
                           f"{t['keypoints'] / t['marked']:.1f}"
                           + (f", {pct(rotation[st])}" if st in rotation else "")
                           for st, t in pooled_all.items()) + ".")
    return (table(["held-out building", "fitted on the other two", "marked points", "5 px, 3x", "10 px, 3x",
                   "keypoints per marked point", "rotation repeatability of the fit (26 shared maps)",
                   "default: 5 px, 3x", "default: 10 px, 3x"], rows), summary)


def fig_robust_lobo(r):
    """The shortest wall and the largest scale, fitted leave-one-building-out."""
    settings = [(ms, mx) for ms in LOBO_MIN_STRENGTH for mx in LOBO_MAX_SCALE]
    block, summary = lobo_fit(
        r, settings, lambda st: ("--min-strength", str(st[0]), "--max-scale", str(st[1])), ROBUST_DEFAULT,
        lambda st: f"min strength {st[0]}, max scale {st[1]}")
    return block + "\n\n" + summary


LOBO_CELL_OCCUPIED = (8, 10, 12, 15, 20)
LOBO_WALL_GAP = (4, 8, 12)
ROBUST_CELLS_DEFAULT = (15, 8)


def fig_robust_lobo_cells(r):
    """The coarse cells' occupied share and the wall gap, fitted leave-one-building-out (the shortest wall
    and the largest scale at their defaults)."""
    settings = [(o, g) for o in LOBO_CELL_OCCUPIED for g in LOBO_WALL_GAP]
    block, summary = lobo_fit(
        r, settings, lambda st: ("--cell-occupied", str(st[0]), "--wall-gap", str(st[1])),
        ROBUST_CELLS_DEFAULT, lambda st: f"occupied {st[0]}%, wall gap {st[1]}")
    # The free share, at the default otherwise: pooled recall only (it moves no marked point, see the text).
    free = []
    for f in (30, 40, 50):
        recs = [x for x in r.json("eval", "--backend", "cpu", "--annotations", CORNERS, PAIR_MAPS,
                                  "--cell-free", str(f)) if x["detector"] == "ogm-robust" and x["map"] != "all"]
        marked = sum(x["marked"] for x in recs)
        free.append(f"free {f}%: {pct(sum(x['hits_5_budget_3x'] for x in recs) / marked)} within 5 px, "
                    f"{pct(sum(x['hits_10_budget_3x'] for x in recs) / marked)} within 10 px")
    return block + "\n\n" + summary + "\n\nThe free share (pooled, at the defaults otherwise): " + "; ".join(free) + "."


LOBO_JOINT_MIN_STRENGTH = (8, 12, 16)


def fig_robust_lobo_joint(r):
    """The shortest wall and the occupied share fitted together, leave-one-building-out (the largest scale
    and the wall gap at their defaults): the share changes which walls the cells see, so which shortest
    wall is best."""
    settings = [(ms, o) for ms in LOBO_JOINT_MIN_STRENGTH for o in LOBO_CELL_OCCUPIED if o >= 10]
    block, summary = lobo_fit(
        r, settings, lambda st: ("--min-strength", str(st[0]), "--cell-occupied", str(st[1])),
        (ROBUST_DEFAULT[0], ROBUST_CELLS_DEFAULT[0]), lambda st: f"min strength {st[0]}, occupied {st[1]}%")
    return block + "\n\n" + summary


def fig_shared_maps(r):
    maps = shared_map_files()
    out = os.path.join(r.work, "compare")
    recs = r.json("compare", *maps, "--backend", "all", "--repeat", "3", "--out", out)
    per_map = open(os.path.join(out, "compare.md")).read().strip()
    rows = []
    for d in DETECTORS:
        xs = [x for x in recs if x["detector"] == d]
        mpx = lambda x: x["width"] * x["height"] / 1e6
        med = lambda k: (f"{statistics.median(x[k] / mpx(x) for x in xs if x[k] is not None):.1f}"
                         if any(x[k] is not None for x in xs) else "-")
        rows.append([d, sum(x["keypoints"] for x in xs), med("cpu_end_to_end_ms"),
                     med("reference_end_to_end_ms"), med("gpu_end_to_end_ms")])
    summary = table(["detector", f"keypoints, all {len(maps)} maps", "median CPU end-to-end ms per Mpx",
                     "median reference end-to-end ms per Mpx", "median GPU (lavapipe) end-to-end ms per Mpx"],
                    rows)
    return (summary + "\n\n<details><summary>Per map (keypoints and median times, ms)</summary>\n\n"
            + per_map + "\n\n</details>")


def fig_repeatability(r):
    recs, _ = repeatability_runs(r)
    if WRITE:
        for f in ("repeatability-noise.png", "repeatability-rotation.png"):
            shutil.copy(os.path.join(r.work, "plots", f), os.path.join(ROOT, "docs", "results", f))
    means = repeatability_means(recs)
    names = ["OGM", "OGM-robust", "Harris", "Shi-Tomasi", "Trajkovic"]
    rot = [m for (c, _), m in sorted(means.items()) if c == "rotation"]
    rows = [["**arbitrary rotation**", "**mean of 15-75 deg**",
             *[f"**{pct(statistics.fmean(m[d] for m in rot))}**" for d in DETECTORS]]]
    order = {"rotation": 0, "rot90": 1, "rot180": 2, "rot270": 3, "mirror": 4, "noise": 5, "overlap": 6}
    for (c, lv), m in sorted(means.items(), key=lambda kv: (order.get(kv[0][0], 9), kv[0][1])):
        level = {"rotation": f"{lv:g} deg", "noise": f"{100 * lv:g}%", "overlap": f"{100 * lv:g}% shared"}.get(c, "-")
        rows.append([c, level, *[pct(m.get(d)) for d in DETECTORS]])
    maps = len({x["map"] for x in recs})
    return (f"Mean over the {maps} maps (over those where the detector has keypoints to repeat: the robust "
            f"detector finds none on some); tolerance 2 px; random conditions 2 seeded trials each; ogm-robust "
            f"at its defaults:\n\n" + table(["condition", "level", *names], rows))


# ---- Merging ----

def fig_pairs(r):
    return r.tool("merge-eval", PAIRS).strip()


def fig_ablation(r):
    return r.tool("merge-eval", PAIRS, "--ablation").strip()


def fig_cross_validate(r):
    return r.tool("merge-eval", PAIRS, "--cross-validate").strip()


MORE = os.path.join(SHARED, "maps-more")


def fig_cross_validate_all(r):
    # The 19 buildings of maps-more cut into a pair file (own cuts at 50 and 30% overlap, and each plan
    # against its furnished copy), judged with the Halmstad pairs, each of the 22 buildings left out.
    if not os.path.isdir(MORE):
        fail(f"{MORE} not found", 2)
    saved = os.path.join(r.work, "more")
    r.tool("merge-eval", "--synthetic", os.path.join(MORE, "ipa"), os.path.join(MORE, "racecar"),
           "--furnished", "--per-map", "4", "--save-pairs", saved)
    return r.tool("merge-eval", "--cross-validate", PAIRS, os.path.join(saved, "pairs.json")).strip()


def fig_families(r):
    return r.tool("merge-eval", "--synthetic", "--per-map", "8").strip()


def fig_partial(r):
    parts = []
    for caption, args in [
        ("The office generator (8 offices, with negatives), `--per-map 4`",
         ["--synthetic", "--family", "office", "--per-map", "4"]),
        ("The 26 maps of `../shared/maps`, `--per-map 4`", ["--synthetic", MAPS, "--per-map", "4"]),
        ("The 22 maps of `../shared/merge-pairs/maps`, `--per-map 2`",
         ["--synthetic", PAIR_MAPS, "--per-map", "2"]),
    ]:
        parts.append(f"**{caption}:**\n\n" + r.tool("merge-eval", *args).strip())
    return "\n\n".join(parts)


def fig_global(r):
    return r.tool("merge-eval", PAIRS, "--global").strip()


def fig_global_scale(r):
    """Mixed synthetic sets of growing size, screened (the default) and, at one size, every pair."""
    runs = [(n, 3) for n in (10, 50, 100, 200, 500)] + [(50, 0)]
    rows, by = [], {}
    for n, k in runs:
        rss = os.path.join(r.work, "time.txt")
        args = ["merge-eval", "--global", "--set-size", n, "--buildings", 4, "--partners", k,
                "--format", "json"]
        out = r.run(["/usr/bin/time", "-f", "%M", "-o", rss, r.bin, *map(str, args)],
                    shown_argv=["ogm-corners", *map(str, args)])
        mb = int(open(rss).read().split()[-1]) / 1024
        row = json.loads(out)[0]
        t = row["timing"]
        total = t["prepare"] + t["align"] + t["place"]
        by[(n, k)] = total
        rows.append([n, "every pair" if k == 0 else k, f"{row['aligned']} of {n * (n - 1) // 2}",
                     row["placed"], row["correct"], row["wrong"], row["groups"], row["foreign"],
                     f"{row['derived_accurate']} of {row['pairs']}", f"{t['prepare']:.1f}",
                     f"{t['align']:.1f}", f"{t['place']:.1f}", f"{total:.1f}", f"{mb:.0f}"])
    import math
    slope = math.log(by[(500, 3)] / by[(50, 3)]) / math.log(500 / 50)
    # The fitted exponent over every screened size from 50 on (least squares in log-log).
    pts = [(math.log(n), math.log(by[(n, 3)])) for n in (50, 100, 200, 500)]
    mx, my = sum(p[0] for p in pts) / len(pts), sum(p[1] for p in pts) / len(pts)
    fit = sum((x - mx) * (y - my) for x, y in pts) / sum((x - mx) ** 2 for x, _ in pts)
    return table(["maps (4 offices)", "partners", "pairs aligned", "placed", "placed correctly",
                  "placed wrongly", "groups", "in another office's group", "derived pairs accurate",
                  "prepare s", "align s", "place s", "total s", "peak MB"], rows) + (
        f"\n\nWall time from 50 to 500 maps grows as N^{slope:.2f} (screened; N^{fit:.2f} fitted over "
        f"50, 100, 200 and 500).")


def fig_ray_scale(r):
    """merge-eval's fleet merged by merge_many locally and on a local Ray instance of 1 and 2 CPUs
    (python/examples/distributed_scale.py, one process a run: its peak memory is its own)."""
    ext, py = python_package(r)
    runs = [(50, "local", 2), (50, "ray", 1), (50, "ray", 2), (200, "local", 2), (200, "ray", 2),
            (1000, "ray", 2)]
    rows, digests = [], {}
    for n, engine, cpus in runs:
        args = ["python/examples/distributed_scale.py", "--size", str(n), "--engine", engine,
                "--cpus", str(cpus)]
        out = r.run([py, *args], env={"PYTHONPATH": ext}, shown_argv=["python", *args])
        row = json.loads(out.strip().splitlines()[-1])
        digests.setdefault(n, set()).add(row["digest"])
        rows.append([n, "this process" if engine == "local" else f"Ray, {cpus} CPU" + ("s" if cpus > 1 else ""),
                     f"{row['pairs_aligned']} of {n * (n - 1) // 2}", row["placed"], row["groups"],
                     f"{row['seconds']:.1f}", f"{row['peak_mb']}",
                     "-" if row["object_store_mb"] is None else f"{row['object_store_mb']}",
                     row["digest"]])
    same = all(len(d) == 1 for d in digests.values())
    return table(["maps (4 offices)", "engine", "pairs aligned", "placed", "groups", "wall s",
                  "this process's peak MB", "preparations in the object store MB", "report digest"],
                 rows) + ("\n\nAt each size every engine gave the same report (digest: every pose and pair "
                          "record)." if same else "\n\nThe engines' reports DIFFER at some size (digests above).")


# ---- Performance ----

def fig_bench_ogm(r):
    b = r.json("bench", "--size", "1024x1024", "--size", "4096x4096", "--size", "16384x16384",
               "--detector", "ogm", "--backend", "cpu,reference", "--repeat", "5")
    rows = []
    for x in b["records"]:
        if x["stage"] != "end_to_end":
            continue
        mem = "" if x.get("peak_rss_ratio") is None else f"{x['peak_rss_ratio']:.2f}"
        rows.append([f"{x['width']}^2", x["backend"], f"{x['median_ms']:.2f}", f"{x['mpx_per_s']:.0f}",
                     x["keypoints"], mem])
    return table(["size", "backend", "median ms", "Mpx/s", "keypoints",
                  "peak resident memory / map bytes"], rows)


def fig_bench_detectors(r):
    b = bench_detectors(r)
    rows = []
    for d in DETECTORS:
        x = end_to_end(b, d)
        rows.append([d, f"{x['median_ms']:.2f}", f"{x['mpx_per_s']:.0f}", x["keypoints"],
                     "" if x.get("peak_rss_mb") is None else f"{x['peak_rss_mb']:.0f}"])
    return ("4096 x 4096 synthetic office, fast CPU path, end to end, median of 10:\n\n"
            + table(["detector", "median ms", "Mpx/s", "keypoints", "peak resident MB (map 17 MB)"], rows))


def fig_bandwidth(r):
    sizes = ["--size", "4096x4096", "--size", "16384x16384"]
    b = r.json("bench", *sizes, "--detector", "all", "--backend", "cpu", "--bandwidth", "--repeat", "10")
    rows = []
    for x in b["records"]:
        if x["stage"] not in ("read", "end_to_end"):
            continue
        name = "plain read of the map (the yardstick)" if x["detector"] == "read" else x["detector"]
        rows.append([f"{x['width']}^2", name, f"{x['median_ms']:.2f}", f"{x['mpx_per_s'] / 1000:.2f}",
                     f"{x['read_percent']:.1f}%"])
    out = (f"All five detectors, fast CPU path ({b['isa']} kernels), end to end, median of 10; the plain read "
           "timed before and after each map's detectors:\n\n"
           + table(["size", "detector", "median ms", "Gpx/s", "share of the read bandwidth"], rows))
    rows = []
    for isa in ("avx512", "avx2", "scalar"):
        argv = [r.bin, "bench", *sizes, "--detector", "ogm", "--backend", "cpu", "--bandwidth", "--repeat", "20",
                "--format", "json"]
        j = json.loads(r.run(argv, env={"OGM_CORNERS_ISA": isa},
                             shown_argv=[f"OGM_CORNERS_ISA={isa}", "ogm-corners", *argv[1:]]))
        ran = j["isa"] + ("" if j["isa"] == isa else f" (asked {isa}: not on this CPU)")
        for x in j["records"]:
            if x["stage"] == "end_to_end":
                rows.append([f"{x['width']}^2", ran, f"{x['median_ms']:.2f}", f"{x['mpx_per_s'] / 1000:.2f}",
                             f"{x['read_percent']:.1f}%"])
    return (out + "\n\nThe paper's detector on each instruction set's kernels (`OGM_CORNERS_ISA`), median of 20:"
            "\n\n" + table(["size", "kernels", "median ms", "Gpx/s", "share of the read bandwidth"], rows))


def fig_gpu_lavapipe(r):
    ogm = r.json("bench", "--size", "1024x1024", "--size", "4096x4096", "--size", "16384x16384",
                 "--detector", "ogm", "--backend", "gpu", "--repeat", "5")
    if not ogm.get("gpu"):
        fail("gpu-lavapipe: no GPU adapter opened (install mesa-vulkan-drivers for lavapipe)")
    base = r.json("bench", "--size", "2048x2048", "--detector", "harris,shi-tomasi,trajkovic",
                  "--backend", "gpu", "--repeat", "5")
    rows = []
    for x in ogm["records"] + base["records"]:
        launches = [("-" if x.get(k) is None else str(x[k])) for k in ("write_passes", "dispatches")]
        rows.append([f"{x['width']}^2", x["detector"], x["stage"], f"{x['median_ms']:.1f}",
                     f"{x['mpx_per_s']:.0f}"] + launches)
    return (f"Adapter: {ogm['gpu']}.\n\n"
            + table(["size", "detector", "stage", "median ms", "Mpx/s", "write passes", "dispatches"], rows))


def fig_opencv(r):
    py = os.path.join(ROOT, "target", "opencv-venv", "bin", "python")
    if not os.path.exists(py):
        fail("opencv: target/opencv-venv is missing (bash scripts/test.sh creates it)")
    out = r.run([py, "benches/opencv_compare.py", "--sizes", "1024,4096", "--repeat", "11", "--bin", r.bin],
                shown_argv=["python3", "benches/opencv_compare.py", "--sizes", "1024,4096", "--repeat", "11"])
    # The synthetic maps in the table, the shared maps' rows folded away (a hundred of them).
    lines = out.strip().split("\n")
    head = [l for l in lines if not l.startswith("|")]
    rows = [l for l in lines if l.startswith("|")]
    top, per_map = rows[:2] + [l for l in rows[2:] if l.startswith("| synthetic |")], \
        rows[:2] + [l for l in rows[2:] if not l.startswith("| synthetic |")]
    return ("\n".join(head).strip() + "\n\n" + "\n".join(top)
            + "\n\n<details><summary>Each shared map</summary>\n\n" + "\n".join(per_map) + "\n\n</details>")


def fig_streamed(r):
    free = shutil.disk_usage(os.path.join(ROOT, "target")).free
    if free < 12e9:
        fail(f"streamed: needs 12 GB free under target/, has {free / 1e9:.1f}")
    d = os.path.join(ROOT, "target", "stream-bench")
    out = r.run(["bash", "scripts/stream-bench.sh", "100000", d], env={"RUNS": "3", "BASELINE_RUNS": "1"},
                shown_argv=["RUNS=3", "BASELINE_RUNS=1", "scripts/stream-bench.sh", "100000"])
    lines = [l for l in out.splitlines() if l.startswith("|")]
    return "\n".join(lines)


def python_package(r):
    """The package with a release build of its extension, in the work folder, and the Python to run it
    (the test environment's: numpy, and the ROS 2 wheels): (its folder, the interpreter)."""
    ext = os.path.join(r.work, "python")
    if not os.path.exists(ext):
        shutil.copytree(os.path.join(ROOT, "python", "ogm_corners"), os.path.join(ext, "ogm_corners"))
        r.run(["cargo", "build", "--release", "--locked", "-p", "ogm-corners-python", "--lib"],
              env={"PYO3_BUILD_EXTENSION_MODULE": "1"})
        r.log.pop()  # the build is not a measurement
        shutil.copy(os.path.join(ROOT, "target", "release", "lib_core.so"),
                    os.path.join(ext, "ogm_corners", "_core.abi3.so"))
    py = os.environ.get("OGM_PYTHON", os.path.join(ROOT, "target", "python-venv", "bin", "python"))
    if not os.path.exists(py):
        fail(f"python: no Python with numpy at {py} (set OGM_PYTHON)")
    return ext, py


def fig_python(r):
    ext, py = python_package(r)
    out = r.run([py, "python/benches/overhead.py", "--cli", r.bin], env={"PYTHONPATH": ext},
                shown_argv=["python", "python/benches/overhead.py", "--cli", "target/release/ogm-corners"])
    return out.strip()


def fig_ros_bench(r):
    ext, py = python_package(r)
    out = r.run([py, "scripts/ros_bench.py"], env={"PYTHONPATH": ext},
                shown_argv=["python", "scripts/ros_bench.py"])
    lines = out.strip().split("\n")
    return lines[0] + ".\n\n" + "\n".join(l for l in lines if l.startswith("|"))


# ---- The README and the guide ----

def fig_demo(r):
    out = r.tool("demo", "--output", os.path.join(r.work, "demo"))
    steps = [l for l in out.strip().split("\n") if not l.startswith("wrote ")]  # then a line per file
    return "```text\n" + "\n".join(steps) + "\n```"


def peak_run(r, *args):
    """The tool run under /usr/bin/time: (seconds, peak resident MB)."""
    rss = os.path.join(r.work, "time.txt")
    r.run(["/usr/bin/time", "-f", "%M", "-o", rss, r.bin, *map(str, args)],
          shown_argv=["ogm-corners", *map(str, args)])
    return r.log[-1][1], int(open(rss).read().split()[-1]) / 1024


def fig_html_cost(r):
    html = os.path.join(r.work, "html")
    plain_s, plain_mb = peak_run(r, "merge-eval", PAIRS)
    html_s, html_mb = peak_run(r, "merge-eval", PAIRS, "--html", html)
    files = [os.path.join(d, f) for d, _, fs in os.walk(html) for f in fs]
    pngs = sum(f.endswith(".png") for f in files)
    size = sum(os.path.getsize(f) for f in files) / 1e6
    return table(["run", "wall s", "peak resident MB", "files written"], [
        ["`merge-eval pairs.json`", f"{plain_s:.1f}", f"{plain_mb:.0f}", "-"],
        ["`merge-eval pairs.json --html DIR`", f"{html_s:.1f}", f"{html_mb:.0f}",
         f"{pngs} pictures, {size:.1f} MB in all"],
    ])


FIGURES = {
    "annotations": ("docs/detectors.md", fig_annotations,
                    "hand-marked corners, pooled (eval --annotations, twice)"),
    "robust-summary": ("docs/detectors.md", fig_robust_summary,
                       "the robust detector against its targets"),
    "robust-lobo": ("docs/detectors.md", fig_robust_lobo,
                    "the robust detector's settings fitted leave-one-building-out, held-out recall"),
    "robust-lobo-cells": ("docs/detectors.md", fig_robust_lobo_cells,
                          "the coarse cells' share and the wall gap fitted leave-one-building-out"),
    "robust-lobo-joint": ("docs/detectors.md", fig_robust_lobo_joint,
                          "the shortest wall and the occupied share fitted together, leave-one-building-out"),
    "shared-maps": ("docs/detectors.md", fig_shared_maps,
                    "every detector on the 26 shared maps (compare --backend all)"),
    "repeatability": ("docs/detectors.md", fig_repeatability,
                      "repeatability on the 26 shared maps, mean over the maps (eval)"),
    "pairs": ("docs/merging.md", fig_pairs,
              "the real pairs (merge-eval)"),
    "ablation": ("docs/merging.md", fig_ablation,
                 "where the hypotheses come from (merge-eval --ablation)"),
    "cross-validate": ("docs/merging.md", fig_cross_validate,
                       "leave-one-building-out (merge-eval --cross-validate)"),
    "cross-validate-all": ("docs/merging.md", fig_cross_validate_all,
                           "leave-one-building-out over the 22 buildings (Halmstad and maps-more)"),
    "families": ("docs/merging.md", fig_families,
                 "hard synthetic families (merge-eval --synthetic --per-map 8)"),
    "partial": ("docs/merging.md", fig_partial,
                "partial overlaps cut from the generator and the shared maps"),
    "global": ("docs/merging.md", fig_global,
               "many maps at once (merge-eval --global)"),
    "global-scale": ("docs/merging.md", fig_global_scale,
                     "many maps at once as the set grows, screened (merge-eval --global --buildings 4)"),
    "ray-scale": ("docs/merging.md", fig_ray_scale,
                  "large merges locally and on Ray with 1 and 2 CPUs (python/examples/distributed_scale.py)"),
    "bench-ogm": ("docs/performance.md", fig_bench_ogm,
                  "the paper's detector, 1024^2 to 16384^2, fast path and reference"),
    "bench-detectors": ("docs/performance.md", fig_bench_detectors,
                        "all five detectors at 4096^2, fast path"),
    "bandwidth": ("docs/performance.md", fig_bandwidth,
                  "every detector as a share of the machine's read bandwidth (bench --bandwidth)"),
    "gpu-lavapipe": ("docs/performance.md", fig_gpu_lavapipe,
                     "the GPU path on the software adapter (lavapipe)"),
    "opencv": ("docs/performance.md", fig_opencv,
               "against OpenCV (benches/opencv_compare.py)"),
    "streamed": ("docs/performance.md", fig_streamed,
                 "a 100000^2 map streamed from disk (scripts/stream-bench.sh)"),
    "demo": ("README.md", fig_demo,
             "what `demo` prints"),
    "html-cost": ("docs/guide.md", fig_html_cost,
                  "what an HTML report costs on the real pairs (merge-eval --html)"),
    "ros-bench": ("docs/ros.md", fig_ros_bench,
                  "the map_merge node on growing maps of the real buildings (scripts/ros_bench.py)"),
    "python": ("docs/performance.md", fig_python,
               "what the Python package adds (python/benches/overhead.py)"),
}


def splice(doc, name, block):
    """The chapter's text with the block between the figure's markers (one pair of them, in order)."""
    path = os.path.join(ROOT, doc)
    lines = open(path, encoding="utf-8").read().split("\n")
    begin, end = f"<!-- figure:{name} -->", f"<!-- /figure:{name} -->"
    if lines.count(begin) != 1 or lines.count(end) != 1 or lines.index(begin) > lines.index(end):
        fail(f"{doc} needs one line '{begin}' before one line '{end}'", 2)
    i, j = lines.index(begin), lines.index(end)
    return "\n".join(lines[: i + 1] + block.split("\n") + lines[j:])


def write_atomic(path, text):
    fd, tmp = tempfile.mkstemp(dir=os.path.dirname(path), prefix="." + os.path.basename(path) + ".")
    with os.fdopen(fd, "w", encoding="utf-8") as f:
        f.write(text)
    os.replace(tmp, path)


def main():
    ap = argparse.ArgumentParser(add_help=False)
    ap.add_argument("--write", action="store_true")
    ap.add_argument("-h", "--help", action="store_true")
    ap.add_argument("names", nargs="*")
    a = ap.parse_args()
    if a.help or not a.names:
        print(USAGE.format(figures="\n".join(f"  {n:16} {doc}: {d}" for n, (doc, _, d) in FIGURES.items())))
        return
    global WRITE
    WRITE = a.write
    names = list(FIGURES) if a.names == ["all"] else a.names
    for n in names:
        if n not in FIGURES:
            fail(f"unknown figure '{n}' (scripts/figures.py lists them)", 2)
    for need in (PAIRS, CORNERS, PAIR_MAPS, MAPS):
        if not os.path.exists(need):
            fail(f"needs the shared data beside the project: {need} is missing", 2)
    if a.write:  # every chapter's markers checked before an hour of measuring
        for n in names:
            splice(FIGURES[n][0], n, "")
    rev, mach, day = commit(), machine(), datetime.date.today().isoformat()
    binary = os.environ.get("OGM_BIN")
    if binary:
        binary = os.path.abspath(binary)
    else:
        subprocess.run(["cargo", "build", "--release", "--locked", "-q", "--bin", "ogm-corners"], cwd=ROOT,
                       check=True)
        binary = os.path.join(ROOT, "target", "release", "ogm-corners")
    with tempfile.TemporaryDirectory(prefix="figures.") as work:
        r = Runner(binary, work)
        for n in names:
            doc, make, _ = FIGURES[n]
            r.log = []
            body = make(r)
            ran = "; ".join(f"`{c}` ({s:.0f} s)" for c, s in r.log)
            if " MAPS" in ran:
                ran += (f"; MAPS: the {len(shared_map_files())} maps of `../shared/maps` (every yaml and png, and"
                        " the stage world's pgm files)")
            stamp = (f"<sub>Measured by `scripts/figures.py {n}` on {day}, commit {rev}, {mach}: {ran}."
                     f"</sub>")
            block = stamp + "\n\n" + body
            print(f"## {n} ({doc})\n\n{block}\n")
            if a.write:
                write_atomic(os.path.join(ROOT, doc), splice(doc, n, block))
                print(f"figures.py: wrote {n} into {doc}", file=sys.stderr)


if __name__ == "__main__":
    main()
