//! The house's layering, checked on the source: no two files of `src/` import each other, directly or
//! through others (a cycle of `use` and `crate::`/`super::` paths), and no file imports a module of a
//! higher layer than its own (the layers `lib.rs` lists, the command line on top). Test modules (`#[cfg(test)]`), comments and string
//! literals are not counted: a test may use anything. A module's own children (`use child::...` in its
//! `mod.rs`, their `super::` back) are part of it and not checked against it; paths inside macros are
//! read as text, so a macro's `crate::` path counts like any other.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Every `.rs` file under `dir`, relative to `root`, `/`-separated.
pub(crate) fn sources(root: &Path, dir: &Path, out: &mut Vec<String>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            sources(root, &p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            let rel = p
                .strip_prefix(root)
                .unwrap()
                .to_string_lossy()
                .replace('\\', "/");
            out.push(rel);
        }
    }
}

/// The module path of a file (`merge/align.rs` -> [merge, align]; `lib.rs`, `main.rs` -> []).
fn module_of(file: &str) -> Vec<String> {
    let mut p: Vec<String> = file
        .trim_end_matches(".rs")
        .split('/')
        .map(String::from)
        .collect();
    if p.last().is_some_and(|s| s == "mod") {
        p.pop();
    }
    if p == ["lib"] || p == ["main"] {
        p.clear();
    }
    p
}

/// The file holding the longest prefix of `segments` that is a module.
fn file_of(src: &Path, segments: &[String]) -> Option<String> {
    let mut best = None;
    for k in 1..=segments.len() {
        let base = segments[..k].join("/");
        for c in [format!("{base}.rs"), format!("{base}/mod.rs")] {
            if src.join(&c).is_file() {
                best = Some(c);
            }
        }
    }
    best
}

/// `a::{b, c::{d}}` as `a::b`, `a::c::d`.
fn expand(s: &str) -> Vec<String> {
    let Some(open) = s.find('{') else {
        return vec![s.to_string()];
    };
    let (head, body) = (&s[..open], &s[open + 1..s.len() - 1]);
    let (mut parts, mut depth, mut cur) = (Vec::new(), 0, String::new());
    for ch in body.chars() {
        match ch {
            '{' => depth += 1,
            '}' => depth -= 1,
            _ => {}
        }
        if ch == ',' && depth == 0 {
            parts.push(std::mem::take(&mut cur));
        } else {
            cur.push(ch);
        }
    }
    parts.push(cur);
    parts
        .iter()
        .filter(|p| !p.is_empty())
        .flat_map(|p| expand(p).into_iter().map(|x| format!("{head}{x}")))
        .collect()
}

/// The paths a file's code names: its `use` statements (expanded) and every `crate::`, `super::` and
/// (in the binary) `ogm_corners::` path elsewhere.
fn paths_in(code: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = String::new();
    let mut i = 0;
    let bytes = code.as_bytes();
    while i < code.len() {
        let at_use = code[i..].starts_with("use ")
            && (i == 0 || !(bytes[i - 1].is_ascii_alphanumeric() || bytes[i - 1] == b'_'));
        if at_use {
            let end = code[i..].find(';').map_or(code.len(), |e| i + e);
            // `a::b as c`: the path is `a::b`.
            let stmt: String = code[i + 4..end]
                .split_whitespace()
                .collect::<Vec<_>>()
                .join(" ")
                .split(" as ")
                .enumerate()
                .map(|(k, part)| {
                    if k == 0 {
                        part
                    } else {
                        // Drop the new name, keep what follows it (`, d::e}` in a group).
                        part.trim_start_matches(|c: char| c.is_alphanumeric() || c == '_')
                    }
                })
                .collect::<String>()
                .replace(' ', "");
            out.extend(expand(&stmt));
            i = end + 1;
        } else {
            let ch = code[i..].chars().next().unwrap();
            rest.push(ch);
            i += ch.len_utf8();
        }
    }
    let ident = |c: char| c.is_ascii_alphanumeric() || c == '_' || c == ':';
    for start in ["crate::", "super::", "ogm_corners::"] {
        let mut from = 0;
        while let Some(k) = rest[from..].find(start) {
            let s = from + k;
            let before = rest[..s].chars().last();
            let end = rest[s..]
                .find(|c: char| !ident(c))
                .map_or(rest.len(), |e| s + e);
            if !before.is_some_and(|c| c.is_ascii_alphanumeric() || c == '_' || c == ':') {
                out.push(rest[s..end].trim_end_matches(':').to_string());
            }
            from = end.max(s + 1);
        }
    }
    out
}

/// Each file's code without comments, string literals and its test module.
fn code_of(text: &str) -> String {
    let text = text.split("#[cfg(test)]").next().unwrap_or("");
    let mut out = String::with_capacity(text.len());
    let (mut in_str, mut escaped) = (false, false);
    let mut chars = text.chars().peekable();
    while let Some(c) = chars.next() {
        if in_str {
            match (escaped, c) {
                (false, '\\') => escaped = true,
                (false, '"') => in_str = false,
                _ => escaped = false,
            }
            if c == '\n' {
                out.push('\n');
            }
            continue;
        }
        match c {
            '"' => {
                in_str = true;
                out.push_str("\"\"");
            }
            // A character literal holding a quote is not a string.
            '\'' if chars.peek() == Some(&'"') => {
                chars.next();
                out.push_str("'\"");
            }
            '/' if chars.peek() == Some(&'/') => {
                for d in chars.by_ref() {
                    if d == '\n' {
                        out.push('\n');
                        break;
                    }
                }
            }
            _ => out.push(c),
        }
    }
    out
}

/// Which files each file imports.
fn graph() -> BTreeMap<String, BTreeSet<String>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    sources(&src, &src, &mut files);
    let mut g = BTreeMap::new();
    for f in &files {
        let code = code_of(&std::fs::read_to_string(src.join(f)).unwrap());
        let me = module_of(f);
        let mut to = BTreeSet::new();
        for p in paths_in(&code) {
            let mut segs: Vec<String> = p.split("::").map(String::from).collect();
            match segs[0].as_str() {
                "crate" | "ogm_corners" => {
                    segs.remove(0);
                }
                "super" => {
                    let mut base = me.clone();
                    while segs.first().is_some_and(|s| s == "super") {
                        base.pop();
                        segs.remove(0);
                    }
                    base.extend(segs);
                    segs = base;
                }
                _ => continue,
            }
            if let Some(t) = file_of(&src, &segs) {
                if &t != f {
                    to.insert(t);
                }
            }
        }
        g.insert(f.clone(), to);
    }
    g
}

/// The files on a cycle through `start`, if any (the shortest, by breadth-first search).
fn cycle_through(g: &BTreeMap<String, BTreeSet<String>>, start: &str) -> Option<Vec<String>> {
    let mut prev: BTreeMap<&str, &str> = BTreeMap::new();
    let mut queue = std::collections::VecDeque::from([start]);
    while let Some(v) = queue.pop_front() {
        for w in &g[v] {
            if w == start {
                let mut path = vec![v.to_string()];
                let mut at = v;
                while at != start {
                    at = prev[at];
                    path.push(at.to_string());
                }
                path.reverse();
                return Some(path);
            }
            if !prev.contains_key(w.as_str()) && g.contains_key(w) {
                prev.insert(w, v);
                queue.push_back(w);
            }
        }
    }
    None
}

#[test]
fn no_file_imports_one_that_imports_it_back() {
    let g = graph();
    assert!(g.len() > 50, "only {} files read", g.len());
    let cycles: BTreeSet<Vec<String>> = g
        .keys()
        .filter_map(|f| cycle_through(&g, f))
        .map(|mut c| {
            // One form of each cycle: starting at its smallest file.
            let k = (0..c.len()).min_by_key(|&i| c[i].clone()).unwrap();
            c.rotate_left(k);
            c
        })
        .collect();
    assert!(
        cycles.is_empty(),
        "import cycles (each file imports the next, the last the first): {cycles:#?}"
    );
}

#[test]
fn the_checker_sees_use_groups_and_paths() {
    let p =
        paths_in("use crate::{a::B, c::{d, e::F}};\nfn x() { super::g::h(); let y = crate::k; }");
    for want in [
        "crate::a::B",
        "crate::c::d",
        "crate::c::e::F",
        "super::g::h",
        "crate::k",
    ] {
        assert!(p.iter().any(|x| x == want), "{want} not in {p:?}");
    }
    assert_eq!(module_of("merge/global/mod.rs"), ["merge", "global"]);
    assert!(code_of("a // crate::x\n#[cfg(test)]\nuse crate::y;").trim() == "a");
    assert!(!code_of("let s = \"use crate::z; // x\"; crate::w();").contains("crate::z"));
    let renamed = paths_in("use crate::a::B as C;\nuse crate::{d::E as F, g::H};");
    for want in ["crate::a::B", "crate::d::E", "crate::g::H"] {
        assert!(
            renamed.iter().any(|x| x == want),
            "{want} not in {renamed:?}"
        );
    }
}

/// The layer of a top-level module, as `lib.rs` lists them bottom to top; the binary's files (`main.rs`,
/// `cli/`) are the top. `None`: a module no layer names (a new one must be given a place).
fn layer_of(file: &str) -> Option<u32> {
    let top = file.split('/').next()?.trim_end_matches(".rs");
    Some(match top {
        "support" => 1,
        "map" => 2,
        // The backend interface, the rule table, the baselines' selection and the reference under the
        // two fast backends.
        "backend" if file.starts_with("backend/fast/") || file.starts_with("backend/gpu/") => 4,
        "backend" => 3,
        "detect" => 5,
        "merge" => 6,
        "measure" => 7,
        "lib" | "main" | "cli" => 8,
        _ => return None,
    })
}

/// Every import that points up the layers, and every file in no layer.
fn upward(g: &BTreeMap<String, BTreeSet<String>>) -> Vec<String> {
    let mut bad = Vec::new();
    for (f, to) in g {
        let Some(lf) = layer_of(f) else {
            bad.push(format!(
                "{f}: its module is in no layer (add it to lib.rs and layer_of)"
            ));
            continue;
        };
        for t in to {
            match layer_of(t) {
                Some(lt) if lt > lf => {
                    bad.push(format!("{f} (layer {lf}) imports {t} (layer {lt})"))
                }
                _ => {}
            }
        }
    }
    bad
}

#[test]
fn no_file_imports_a_higher_layer() {
    let bad = upward(&graph());
    assert!(bad.is_empty(), "{} upward imports: {bad:#?}", bad.len());
}

#[test]
fn the_layer_checker_sees_an_upward_import() {
    let edge = |f: &str, t: &str| (f.to_string(), BTreeSet::from([t.to_string()]));
    let g = BTreeMap::from([
        edge("detect/robust/corners.rs", "merge/align.rs"),
        edge("map/yaml.rs", "backend/mod.rs"),
        edge("backend/reference/scan.rs", "backend/gpu/scan.rs"),
        edge("backend/gpu/scan.rs", "backend/reference/scan.rs"),
        edge("merge/align.rs", "detect/robust/corners.rs"),
        edge("nowhere.rs", "support/error.rs"),
    ]);
    let bad = upward(&g);
    assert_eq!(bad.len(), 4, "{bad:#?}");
    for (k, from) in [
        "backend/reference",
        "detect/robust",
        "map/yaml.rs",
        "nowhere.rs",
    ]
    .iter()
    .enumerate()
    {
        assert!(bad[k].starts_with(from), "{bad:#?}");
    }
}

/// The backends' implementations (the reference, the fast path, the GPU), behind the interface that
/// `backend/mod.rs` is.
fn is_backend_implementation(file: &str) -> bool {
    ["backend/reference/", "backend/fast/", "backend/gpu/"]
        .iter()
        .any(|d| file.starts_with(d))
}

/// Reaches past the backend interface: a file of the detectors or the merger importing an
/// implementation's file, other than the detector's choice of backend (`detect/detector.rs`, which
/// constructs them) and the reaches `allowed` lists.
fn past_the_interface(
    g: &BTreeMap<String, BTreeSet<String>>,
    allowed: &[(&str, &str)],
) -> Vec<String> {
    let mut bad = Vec::new();
    for (f, to) in g {
        let algorithm = f.starts_with("detect/") || f.starts_with("merge/");
        if !algorithm || f == "detect/detector.rs" {
            continue;
        }
        for t in to.iter().filter(|t| is_backend_implementation(t)) {
            if !allowed.contains(&(f.as_str(), t.as_str())) {
                bad.push(format!(
                    "{f} imports {t}, past the backend interface (backend/mod.rs)"
                ));
            }
        }
    }
    bad
}

/// The one reach left: the robust detector's wall-direction histogram packs rows into bit-planes with
/// the fast path's SIMD classification, which no backend computes for it.
const ALLOWED_REACHES: &[(&str, &str)] =
    &[("detect/robust/orientation.rs", "backend/fast/bitplanes.rs")];

#[test]
fn the_detectors_and_the_merger_use_backends_through_the_interface() {
    let g = graph();
    let bad = past_the_interface(&g, ALLOWED_REACHES);
    assert!(bad.is_empty(), "{bad:#?}");
    // Each allowed reach is still made (a mended one leaves the list).
    for (f, t) in ALLOWED_REACHES {
        assert!(
            g[*f].contains(*t),
            "{f} no longer imports {t}: drop it from ALLOWED_REACHES"
        );
    }
}

#[test]
fn the_interface_checker_sees_a_reach_past_it() {
    let edge = |f: &str, t: &str| (f.to_string(), BTreeSet::from([t.to_string()]));
    let g = BTreeMap::from([
        edge("merge/score.rs", "backend/reference/merge_score.rs"),
        edge("merge/align.rs", "backend/mod.rs"),
        edge("detect/detector.rs", "backend/gpu/mod.rs"),
        edge("bench.rs", "backend/fast/read.rs"),
    ]);
    let bad = past_the_interface(&g, &[]);
    assert_eq!(bad.len(), 1, "{bad:#?}");
    assert!(bad[0].starts_with("merge/score.rs"));
}

/// Within the merger: two maps (`merge/pair/`) and what both use (`merge/*.rs`) below many maps
/// (`merge/many/`), which place the pairs the two-map aligner gives.
fn many_reached_from_below(g: &BTreeMap<String, BTreeSet<String>>) -> Vec<String> {
    let mut bad = Vec::new();
    for (f, to) in g {
        if !f.starts_with("merge/") || f.starts_with("merge/many/") || f == "merge/mod.rs" {
            continue;
        }
        for t in to.iter().filter(|t| t.starts_with("merge/many/")) {
            bad.push(format!("{f} imports {t}: many maps sit above the pair"));
        }
    }
    bad
}

#[test]
fn the_pair_never_imports_the_many_map_merger() {
    let bad = many_reached_from_below(&graph());
    assert!(bad.is_empty(), "{bad:#?}");
    let edge = |f: &str, t: &str| (f.to_string(), BTreeSet::from([t.to_string()]));
    let g = BTreeMap::from([
        edge("merge/pair/align.rs", "merge/many/graph.rs"),
        edge("merge/many/graph.rs", "merge/pair/align.rs"),
        edge("merge/compose.rs", "merge/many/mosaic.rs"),
    ]);
    assert_eq!(many_reached_from_below(&g).len(), 2);
}
