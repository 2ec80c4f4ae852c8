"""Browser tests of the static HTML reports (`--html DIR`), in headless Chromium over W3C WebDriver.

Run: target/python-venv/bin/python -m pytest tests/browser
Needs Chromium and chromedriver (Debian: `apt-get install chromium chromium-driver`); without them the tests
say SKIPPED (and fail under CI=true). The report tests need the CLI: $OGM_CORNERS_BIN, or
target/debug/ogm-corners, or target/release/ogm-corners. Full-page screenshots go to target/browser/.

The page contract checked (what the generator writes):
- every data table is `<table class="report" id=ID data-rows=N>` with `<thead><tr><th data-type="num|text">`
  and exactly N `<tr>` in its `<tbody>`, each with one cell per column;
- a `<td data-key=K>` sorts by K ("" = missing); without data-key by its text; num columns by the number
  (parseFloat), missing (or not a number) last;
- a click on a `<th>` sorts ascending (missing last), a second click descending (missing still last); the
  `<th>` then has aria-sort="ascending" / "descending";
- every `<img>` loads (relative PNGs beside the page); `<h1>` holds the title; no console errors.
"""

from __future__ import annotations

import json
import math
import os
import re
import struct
import subprocess
import sys
import warnings
import zlib
from collections import Counter
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
import webdriver  # noqa: E402  (this folder's WebDriver client)

REPO = Path(__file__).resolve().parents[2]
SHOT_DIR = REPO / "target" / "browser"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


# ---------------------------------------------------------------------------------------------------
# Fixtures
# ---------------------------------------------------------------------------------------------------


def _unavailable(reason: str) -> None:
    """Skip loudly, or fail under CI=true (where a skipped browser test would hide a broken setup)."""
    if os.environ.get("CI") == "true":
        pytest.fail(f"CI=true and {reason}", pytrace=False)
    pytest.skip(f"SKIPPED: {reason}")


@pytest.fixture(scope="module")
def browser():
    """One headless Chromium session for the module (about a second to start); closed, with every
    process it started, at the end."""
    if not webdriver.available():
        _unavailable("the browser tests need " + " and ".join(webdriver.missing()))
    with webdriver.Browser() as b:
        yield b


@pytest.fixture(scope="module")
def cli() -> Path:
    """The ogm-corners binary: $OGM_CORNERS_BIN, else target/debug, else target/release."""
    env = os.environ.get("OGM_CORNERS_BIN")
    if env:
        p = Path(env)
        if not (p.is_file() and os.access(p, os.X_OK)):
            pytest.fail(f"OGM_CORNERS_BIN={env} is not an executable file", pytrace=False)
        return p
    for profile in ("debug", "release"):
        p = REPO / "target" / profile / "ogm-corners"
        if p.is_file() and os.access(p, os.X_OK):
            return p
    _unavailable(
        "no ogm-corners binary (set OGM_CORNERS_BIN, or `cargo build` for target/debug/ogm-corners)"
    )


# ---------------------------------------------------------------------------------------------------
# The page check
# ---------------------------------------------------------------------------------------------------

# Every table.report: id, data-rows, the tbody rows, the header labels and types, rows whose cell count
# differs from the header's.
_TABLES_JS = r"""
return Array.from(document.querySelectorAll("table.report")).map(function (t) {
  var ths = Array.from(t.querySelectorAll(":scope > thead > tr > th"));
  var rows = Array.from(t.querySelectorAll(":scope > tbody > tr"));
  var ragged = [];
  rows.forEach(function (tr, i) { if (tr.cells.length !== ths.length) ragged.push([i, tr.cells.length]); });
  return {
    id: t.id,
    dataRows: t.getAttribute("data-rows"),
    rows: rows.length,
    labels: ths.map(function (th) { return th.textContent.trim(); }),
    types: ths.map(function (th) { return th.getAttribute("data-type"); }),
    ragged: ragged.slice(0, 5),
    raggedCount: ragged.length
  };
});
"""

# Images: [src, complete, naturalWidth]; incomplete ones (lazy loading) are scrolled into view.
_IMAGES_JS = r"""
return Array.from(document.images).map(function (img) {
  if (!img.complete) img.scrollIntoView();
  return [img.getAttribute("src"), img.complete, img.naturalWidth];
});
"""

# The <th> of table arguments[0] whose text is arguments[1], or the labels there are.
_TH_JS = r"""
var t = document.getElementById(arguments[0]);
if (!t || !t.matches("table.report")) return {error: "no table.report with id " + JSON.stringify(arguments[0])};
var ths = Array.from(t.querySelectorAll(":scope > thead > tr > th"));
for (var i = 0; i < ths.length; i++) {
  if (ths[i].textContent.trim() === arguments[1]) return {th: ths[i], index: i, type: ths[i].getAttribute("data-type")};
}
return {error: "no column " + JSON.stringify(arguments[1]) + " in table " + arguments[0] + "; its columns: "
        + JSON.stringify(ths.map(function (h) { return h.textContent.trim(); }))};
"""

# The table's state after a sort: the column's raw keys in DOM order (data-key, else the text), the
# aria-sort of the header, and each row's content (to check rows moved whole).
_STATE_JS = r"""
var t = document.getElementById(arguments[0]), col = arguments[1];
var th = t.querySelectorAll(":scope > thead > tr > th")[col];
var rows = Array.from(t.querySelectorAll(":scope > tbody > tr"));
return {
  aria: th.getAttribute("aria-sort"),
  keys: rows.map(function (tr) {
    var td = tr.cells[col];
    return td.hasAttribute("data-key") ? td.getAttribute("data-key") : td.textContent.trim();
  }),
  rows: rows.map(function (tr) {
    return Array.from(tr.cells).map(function (td) {
      return (td.getAttribute("data-key") || "") + "\u001f" + td.textContent;
    }).join("\u001e");
  })
};
"""

# Whether strings are in order by the browser's collation (localeCompare), ascending or descending.
_LOCALE_SORTED_JS = r"""
var k = arguments[0], sign = arguments[1] ? -1 : 1;
for (var i = 1; i < k.length; i++) if (sign * k[i - 1].localeCompare(k[i]) > 0) return false;
return true;
"""

_FLOAT_PREFIX = re.compile(r"\s*([+-]?(?:Infinity|(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?))")


def parse_num_key(key: str) -> float | None:
    """A num column's key as JavaScript's parseFloat reads it; None (missing) for "" or not a number."""
    m = _FLOAT_PREFIX.match(key)
    if not m:
        return None
    s = m.group(1).replace("Infinity", "inf")
    v = float(s)
    return None if math.isnan(v) else v


def _check_sorted(browser, table: str, label: str, kind: str, keys: list[str], descending: bool) -> None:
    """Missing keys all last; the others in order (numbers by value; text by code point or the browser's
    collation, whichever the page uses)."""
    where = f"table {table!r}, column {label!r} ({'descending' if descending else 'ascending'})"
    if kind == "num":
        vals = [parse_num_key(k) for k in keys]
    else:
        vals = [k if k != "" else None for k in keys]
    present = [v for v in vals if v is not None]
    first_missing = next((i for i, v in enumerate(vals) if v is None), len(vals))
    assert all(v is None for v in vals[first_missing:]), (
        f"{where}: a missing value is not last; keys in DOM order: {keys}"
    )
    if kind == "num":
        pairs = zip(present, present[1:])
        bad = [(a, b) for a, b in pairs if (a < b if descending else a > b)]
        assert not bad, f"{where}: out of order at {bad[:3]}; keys in DOM order: {keys}"
    else:
        by_code = present == sorted(present, reverse=descending)
        by_locale = browser.script(_LOCALE_SORTED_JS, present, descending)
        assert by_code or by_locale, (
            f"{where}: out of order (by code point and by localeCompare); keys in DOM order: {keys}"
        )


def check_report(
    browser: webdriver.Browser,
    index_html_path: str | os.PathLike,
    expected_rows: dict[str, int],
    sort_table: str,
    sort_column_label: str,
    shot_name: str,
    *,
    expect_images: bool = False,
    shot_dir: str | os.PathLike | None = None,
) -> dict:
    """Open a report page from file:// and check it against the contract (module docstring): the title;
    every table's rows against its data-rows and each `expected_rows[id]` (counted independently, e.g.
    from the CLI's JSON); every image loaded (and at least one if `expect_images`); a click on
    `sort_column_label` of table `sort_table` sorts ascending, a second click descending; no console
    errors. Saves a full-page screenshot `shot_dir/shot_name.png` (default target/browser/).
    Returns what it saw: title, tables, images, screenshot path."""
    page = Path(index_html_path).resolve()
    assert page.is_file(), f"no report page at {page}"
    browser.console()  # drop earlier pages' entries
    browser.open(page.as_uri())

    title = browser.script("var h = document.querySelector('h1'); return h ? h.textContent.trim() : null;")
    assert title, f"{page}: no <h1> title, or an empty one"

    # Tables: the DOM's rows against data-rows, and against the independent counts.
    tables = browser.script(_TABLES_JS)
    by_id = {t["id"]: t for t in tables}
    ids = [t["id"] for t in tables]
    dupes = [i for i, n in Counter(ids).items() if n > 1]
    assert not dupes, f"{page}: table ids not unique: {dupes}"
    for t in tables:
        assert t["id"], f"{page}: a table.report without an id (columns {t['labels']})"
        assert t["dataRows"] is not None and re.fullmatch(r"\d+", t["dataRows"]), (
            f"table {t['id']!r}: data-rows missing or not a count: {t['dataRows']!r}"
        )
        assert t["rows"] == int(t["dataRows"]), (
            f"table {t['id']!r}: {t['rows']} rows in the tbody, data-rows says {t['dataRows']}"
        )
        assert t["labels"], f"table {t['id']!r}: no <th> in its thead"
        bad_types = [(l, ty) for l, ty in zip(t["labels"], t["types"]) if ty not in ("num", "text")]
        assert not bad_types, f"table {t['id']!r}: th data-type not num|text: {bad_types}"
        assert t["raggedCount"] == 0, (
            f"table {t['id']!r}: {t['raggedCount']} rows whose cell count differs from the "
            f"{len(t['labels'])} columns, e.g. (row, cells) {t['ragged']}"
        )
    for tid, n in expected_rows.items():
        assert tid in by_id, f"{page}: no table.report with id {tid!r}; the tables: {ids}"
        assert by_id[tid]["rows"] == n, (
            f"table {tid!r}: {by_id[tid]['rows']} rows on the page, expected {n} (from the CLI's output)"
        )

    # Images: wait for any still loading (lazy ones are scrolled to), then every one must have pixels.
    images = browser.script(_IMAGES_JS)
    for _ in range(100):
        if all(complete for _, complete, _ in images):
            break
        browser.script("return new Promise(function (r) { setTimeout(r, 100); });")
        images = browser.script(_IMAGES_JS)
    failed = [src for src, complete, width in images if not (complete and width > 0)]
    assert not failed, f"{page}: {len(failed)} of {len(images)} images did not load: {failed[:20]}"
    if expect_images:
        assert images, f"{page}: no <img> on the page, pictures were expected"

    # Sorting, by real clicks on the header.
    found = browser.script(_TH_JS, sort_table, sort_column_label)
    assert "error" not in found, f"{page}: {found.get('error')}"
    th, col, kind = found["th"], found["index"], found["type"]
    before = browser.script(_STATE_JS, sort_table, col)
    distinct = {k for k in before["keys"] if k != ""}
    if len(distinct) < 2:
        warnings.warn(
            f"{page}: table {sort_table!r} column {sort_column_label!r} has fewer than two distinct keys; "
            "the sort check proves little",
            stacklevel=2,
        )
    for click, (aria, descending) in enumerate((("ascending", False), ("descending", True)), 1):
        browser.click(th)
        after = browser.script(_STATE_JS, sort_table, col)
        assert after["aria"] == aria, (
            f"table {sort_table!r}, column {sort_column_label!r}: after click {click} aria-sort is "
            f"{after['aria']!r}, expected {aria!r}"
        )
        assert Counter(after["rows"]) == Counter(before["rows"]), (
            f"table {sort_table!r}: sorting by {sort_column_label!r} changed the rows' contents "
            "(rows must move whole)"
        )
        _check_sorted(browser, sort_table, sort_column_label, kind, after["keys"], descending)

    # The page's own script threw nothing, and nothing failed to load.
    errors = [e.get("message", "") for e in browser.console() if e.get("level") == "SEVERE"]
    assert not errors, f"{page}: console errors: {errors[:10]}"

    # Full-page screenshot.
    shot = Path(shot_dir or SHOT_DIR) / f"{shot_name}.png"
    browser.screenshot(shot, full_page=True)
    data = shot.read_bytes() if shot.is_file() else b""
    assert len(data) > len(PNG_MAGIC) and data.startswith(PNG_MAGIC), f"{shot}: not a PNG screenshot"
    return {"title": title, "tables": tables, "images": len(images), "screenshot": shot}


# ---------------------------------------------------------------------------------------------------
# The report tests: the CLI writes a report, the page is checked against the CLI's own JSON.
# ---------------------------------------------------------------------------------------------------

COMPARE_SORT = "keypoints"  # a column of compare::html_table (src/compare.rs)
COMPARE_IMAGES = True  # the contact sheets
EVAL_SORT = "repeatability %"
EVAL_IMAGES = True  # the plots and the contact sheets
MERGE_EVAL_SORT = "score"
MERGE_EVAL_IMAGES = True  # the pairs' overlays
MERGE_SORT = "map"
MERGE_IMAGES = True  # the group picture and each map


def run_cli(cli: Path, *args, timeout: float = 900) -> subprocess.CompletedProcess:
    """Run the CLI; fail with its stderr unless it exits 0."""
    cmd = [str(cli), *(str(a) for a in args)]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    assert r.returncode == 0, (
        f"`{' '.join(cmd)}` exited with {r.returncode}\n--- stderr (tail) ---\n{r.stderr[-4000:]}"
    )
    return r


def cli_json(r: subprocess.CompletedProcess):
    """The CLI's JSON output (stdout)."""
    try:
        return json.loads(r.stdout)
    except ValueError as e:
        pytest.fail(f"`{' '.join(r.args)}`: stdout is not JSON ({e}): {r.stdout[:500]!r}", pytrace=False)


@pytest.fixture(scope="module")
def office_map(cli, tmp_path_factory) -> Path:
    """A small synthetic office map (400x300, seed 3), written by `bench --write-map`."""
    out = tmp_path_factory.mktemp("maps") / "office.pgm"
    run_cli(cli, "bench", "--size", "400x300", "--seed", "3", "--write-map", out)
    assert out.is_file(), f"bench --write-map wrote no {out}"
    return out


def test_compare_report(cli, browser, office_map, tmp_path):
    """REPORT TEST `compare --html`: table `compare` has one row per JSON record; contact sheets load;
    sorting works."""
    html = tmp_path / "html"
    r = run_cli(cli, "compare", office_map, "--html", html, "--out", tmp_path / "out", "--format", "json",
                "--repeat", "1", "--backend", "cpu")
    records = cli_json(r)
    assert isinstance(records, list) and records, (
        f"compare --format json: expected a non-empty list: {str(records)[:500]}"
    )
    check_report(browser, html / "index.html", {"compare": len(records)}, "compare", COMPARE_SORT,
                 "compare", expect_images=COMPARE_IMAGES)


def test_eval_report(cli, browser, office_map, tmp_path):
    """REPORT TEST `eval --html`: table `eval` has one row per JSON record; sorting works."""
    html = tmp_path / "html"
    r = run_cli(cli, "eval", office_map, "--trials", "1", "--format", "json", "--html", html,
                "--backend", "cpu")
    records = cli_json(r)
    assert isinstance(records, list) and records, (
        f"eval --format json: expected a non-empty list: {str(records)[:500]}"
    )
    check_report(browser, html / "index.html", {"eval": len(records)}, "eval", EVAL_SORT, "eval",
                 expect_images=EVAL_IMAGES)


def test_merge_eval_report(cli, browser, tmp_path):
    """REPORT TEST `merge-eval --synthetic --html`: table `pairs` has one row per pair record; sorting by
    `score` works."""
    html = tmp_path / "html"
    r = run_cli(cli, "merge-eval", "--synthetic", "--per-map", "1", "--format", "json", "--html", html)
    records = cli_json(r)
    assert isinstance(records, list) and records, (
        f"merge-eval --format json: expected a non-empty list: {str(records)[:500]}"
    )
    # As written, worst first: wrong accepts, then missed pairs, then the rest (the verdict column's key is
    # that rank); one picture per pair, anchored where the pair's number links.
    browser.open((html / "index.html").resolve().as_uri())
    ranks = browser.script(
        "return Array.from(document.querySelectorAll('table#pairs tbody tr'))"
        ".map(tr => parseFloat(tr.cells[4].getAttribute('data-key')))"
    )
    assert len(ranks) == len(records) and ranks == sorted(ranks), f"pairs not worst first: {ranks}"
    declined = sum(1 for r in records if not r["negative"] and not r["accepted"])
    assert ranks.count(2) + ranks.count(1) == declined, (ranks, declined)
    anchors = browser.script(
        "return Array.from(document.querySelectorAll('table#pairs tbody a'))"
        ".filter(a => !document.getElementById(a.getAttribute('href').slice(1))).length"
    )
    assert anchors == 0, f"{anchors} pair links lead nowhere"
    figures = browser.script("return document.querySelectorAll('figure[id^=\"pair-\"]').length")
    assert figures == len(records), f"{figures} pair pictures for {len(records)} pairs"
    check_report(browser, html / "index.html", {"pairs": len(records)}, "pairs", MERGE_EVAL_SORT,
                 "merge-eval", expect_images=MERGE_EVAL_IMAGES)


def test_merge_many_report(cli, browser, tmp_path):
    """REPORT TEST `merge DIR --html` (many maps): the set from `merge-eval --global --set-size 4
    --save-pairs` (part-NN.pgm and a pairs.json, which the folder search may skip with a note); table
    `maps` has one row per entry of the JSON's "maps"."""
    sets = tmp_path / "set"
    run_cli(cli, "merge-eval", "--global", "--set-size", "4", "--save-pairs", sets)
    parts = sorted(sets.glob("part-*.pgm"))
    assert len(parts) == 4, f"merge-eval --global --set-size 4 wrote {[p.name for p in parts]}"
    html = tmp_path / "html"
    r = run_cli(cli, "merge", sets, "--html", html, "--format", "json")
    doc = cli_json(r)
    assert isinstance(doc, dict) and isinstance(doc.get("maps"), list), (
        f"merge --format json: expected an object with a \"maps\" list: {str(doc)[:500]}"
    )
    assert len(doc["maps"]) == len(parts), (
        f"merge --format json lists {len(doc['maps'])} maps, the set has {len(parts)}"
    )
    check_report(browser, html / "index.html", {"maps": len(doc["maps"])}, "maps", MERGE_SORT, "merge",
                 expect_images=MERGE_IMAGES)


# ---------------------------------------------------------------------------------------------------
# Self-test of the harness: a hand-written page that follows the contract (with its own sorter, not the
# generator's), and broken variants the check must reject. Needs the browser only, not the CLI.
# ---------------------------------------------------------------------------------------------------


def _png(width: int, height: int) -> bytes:
    """A small RGB PNG (a gradient), standard library only."""
    raw = b"".join(
        b"\x00" + bytes(c for x in range(width) for c in (x * 255 // width, y * 255 // height, 128))
        for y in range(height)
    )

    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return PNG_MAGIC + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")


# Sorts by the clicked column: missing last in both directions, numbers by value, text by localeCompare.
_SAMPLE_SORTER = r"""
for (const th of document.querySelectorAll("table.report > thead > tr > th")) {
  th.addEventListener("click", () => {
    const table = th.closest("table"), tbody = table.tBodies[0], col = th.cellIndex;
    const num = th.dataset.type === "num";
    const desc = th.getAttribute("aria-sort") === "ascending";
    for (const h of table.tHead.rows[0].cells) h.removeAttribute("aria-sort");
    th.setAttribute("aria-sort", desc ? "descending" : "ascending");
    const key = (tr) => {
      const td = tr.cells[col];
      const k = td.hasAttribute("data-key") ? td.dataset.key : td.textContent.trim();
      if (k === "") return null;
      if (!num) return k;
      const v = parseFloat(k);
      return Number.isNaN(v) ? null : v;
    };
    const rows = [...tbody.rows].map((tr) => [key(tr), tr]);
    rows.sort(([a], [b]) => {
      if (a === null || b === null) return (a === null) - (b === null);
      const c = num ? a - b : a.localeCompare(b);
      return desc ? -c : c;
    });
    for (const [, tr] of rows) tbody.appendChild(tr);
  });
}
"""

# The sample's tables: (id, columns as (label, type), rows as cells (text, data-key or None)).
_SAMPLE_TABLES = [
    (
        "pairs",
        [("pair", "text"), ("score", "num"), ("error px", "num")],
        [
            [("office-1-50-0", None), ("0.91", "0.9132"), ("-", "")],
            [("office-2-50-0", None), ("0.15", "0.1499"), ("3.2", None)],
            [("office-10-30-0", None), ("-", ""), ("12.0", None)],
            [("Office-3-30-0", None), ("0.73", "0.73"), ("0.4", None)],
            [("office-4-30-1", None), ("2.50", "2.5"), ("", None)],
            [("office-5-50-1", None), ("10.5", "10.5"), ("2", None)],
        ],
    ),
    (
        "maps",
        [("map", "text"), ("group", "num")],
        [[("part-00", None), ("0", None)], [("part-01", None), ("1", None)], [("part-02", None), ("0", None)]],
    ),
]


def write_sample_page(folder: Path, sorter: str = _SAMPLE_SORTER, img_src: str = "pic-1.png") -> Path:
    """A page that follows the contract in `folder` (index.html, two PNGs beside it)."""
    from html import escape

    folder.mkdir(parents=True, exist_ok=True)
    (folder / "pic-1.png").write_bytes(_png(64, 48))
    (folder / "pic-2.png").write_bytes(_png(32, 32))
    parts = ["<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>Sample report</title>",
             "<style>table{border-collapse:collapse}th,td{border:1px solid #ccc;padding:2px 6px}"
             "th{cursor:pointer;position:sticky;top:0;background:#eee}</style></head><body>",
             "<h1>Sample report</h1>"]
    for tid, cols, rows in _SAMPLE_TABLES:
        parts.append(f'<table class="report" id="{tid}" data-rows="{len(rows)}"><thead><tr>')
        parts += [f'<th data-type="{ty}">{escape(label)}</th>' for label, ty in cols]
        parts.append("</tr></thead><tbody>")
        for row in rows:
            cells = "".join(
                f"<td{'' if key is None else f' data-key={chr(34)}{escape(key)}{chr(34)}'}>{escape(text)}</td>"
                for text, key in row
            )
            parts.append(f"<tr>{cells}</tr>")
        parts.append("</tbody></table>")
    # A tall spacer so the full-page screenshot has something below the first screen.
    parts.append('<div style="height:2500px"></div>')
    parts.append(f'<figure><img src="{escape(img_src)}" alt="first" width="320"></figure>')
    parts.append('<figure><img src="pic-2.png" alt="second" loading="lazy"></figure>')
    parts.append(f"<script>{sorter}</script></body></html>\n")
    page = folder / "index.html"
    page.write_text("".join(parts), encoding="utf-8")
    return page


SAMPLE_ROWS = {"pairs": 6, "maps": 3}


def test_selftest_sample_page(browser, tmp_path):
    """Harness self-test: a correct page passes (sorting both a num and a text column)."""
    page = write_sample_page(tmp_path / "ok")
    seen = check_report(browser, page, SAMPLE_ROWS, "pairs", "score", "selftest", expect_images=True,
                        shot_dir=tmp_path)
    assert seen["images"] == 2 and seen["title"] == "Sample report"
    check_report(browser, page, {}, "pairs", "pair", "selftest-text", shot_dir=tmp_path)
    check_report(browser, page, {}, "pairs", "error px", "selftest-err", shot_dir=tmp_path)


def _edit(old: str, new: str):
    def apply(text: str) -> str:
        assert old in text, f"self-test edit does not apply: {old!r}"
        return text.replace(old, new)
    return apply


# Broken variants of the sample: (sorter edits, page edits, image src, expected rows, column, the message
# the check must fail with).
_BROKEN = {
    "numbers sorted as text": (
        [_edit("const c = num ? a - b : a.localeCompare(b);", "const c = String(a).localeCompare(String(b));")],
        [], None, {}, "score", r"out of order",
    ),
    "missing first": (
        [_edit("return (a === null) - (b === null);", "return (b === null) - (a === null);")],
        [], None, {}, "score", r"missing value is not last",
    ),
    "missing first when descending": (
        [_edit("return (a === null) - (b === null);",
               "return desc ? (b === null) - (a === null) : (a === null) - (b === null);")],
        [], None, {}, "score", r"\(descending\): a missing value is not last",
    ),
    "second click not descending": (
        [_edit("return desc ? -c : c;", "return c;")],
        [], None, {}, "score", r"\(descending\): out of order",
    ),
    "text second click not descending": (
        [_edit("return desc ? -c : c;", "return c;")],
        [], None, {}, "pair", r"\(descending\): out of order",
    ),
    "no aria-sort": (
        [_edit('th.setAttribute("aria-sort", desc ? "descending" : "ascending");',
               'th.setAttribute("data-sorted", desc ? "descending" : "ascending");'),
         _edit('const desc = th.getAttribute("aria-sort") === "ascending";',
               'const desc = th.getAttribute("data-sorted") === "ascending";')],
        [], None, {}, "score", r"aria-sort is None",
    ),
    "cells moved, not rows": (
        [_edit("for (const [, tr] of rows) tbody.appendChild(tr);",
               "const cells = rows.map(([, tr]) => tr.cells[col].outerHTML);"
               " [...tbody.rows].forEach((tr, i) => { tr.cells[col].outerHTML = cells[i]; });")],
        [], None, {}, "score", r"rows must move whole",
    ),
    "script error": (
        [_edit("for (const [, tr] of rows) tbody.appendChild(tr);",
               "for (const [, tr] of rows) tbody.appendChild(tr); setTimeout(() => { throw new Error('late'); });")],
        [], None, {}, "score", r"console errors",
    ),
    "broken image": ([], [], "no-such.png", {}, "score", r"images did not load: \['no-such.png'\]"),
    "data-rows wrong": ([], [_edit('data-rows="6"', 'data-rows="7"')], None, {}, "score",
                        r"6 rows in the tbody, data-rows says 7"),
    "row short of a cell": ([], [_edit('<td>office-2-50-0</td>', '')], None, {}, "score",
                            r"cell count differs"),
    "rows not as expected": ([], [], None, {"pairs": 5}, "score", r"6 rows on the page, expected 5"),
    "no such column": ([], [], None, {}, "scores", r"no column \"scores\""),
}


@pytest.mark.parametrize("case", list(_BROKEN))
def test_selftest_sample_page_broken(browser, tmp_path, case):
    """Harness self-test: the check rejects a page that breaks the contract."""
    sorter_edits, page_edits, img_src, rows, column, message = _BROKEN[case]
    sorter = _SAMPLE_SORTER
    for e in sorter_edits:
        sorter = e(sorter)
    page = write_sample_page(tmp_path / "page", sorter=sorter, img_src=img_src or "pic-1.png")
    text = page.read_text(encoding="utf-8")
    for e in page_edits:
        text = e(text)
    page.write_text(text, encoding="utf-8")
    with pytest.raises(AssertionError, match=message):
        check_report(browser, page, rows, "pairs", column, "selftest-broken", shot_dir=tmp_path)
