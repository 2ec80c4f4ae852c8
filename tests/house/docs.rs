//! The documentation's own checks: every measured block between figure markers is one that
//! `scripts/figures.py` writes (so it can be measured again on the revision that states it), every link
//! between the pages reaches a file and a heading that exist, the files and module paths the pages name
//! exist, no chapter carries dated history (that goes to docs/design/ or the CHANGELOG), and the product
//! never names the tracker's issue numbers.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// README, CHANGELOG, CONTRIBUTING, every chapter under docs/ and every design note under docs/design/, as
/// (path relative to the root, text).
fn pages() -> Vec<(String, String)> {
    let mut names = vec![
        "README.md".to_string(),
        "CHANGELOG.md".to_string(),
        "CONTRIBUTING.md".to_string(),
    ];
    for dir in ["docs", "docs/design"] {
        for e in std::fs::read_dir(root().join(dir)).unwrap() {
            let p = e.unwrap().path();
            if p.extension().is_some_and(|x| x == "md") {
                names.push(format!(
                    "{dir}/{}",
                    p.file_name().unwrap().to_string_lossy()
                ));
            }
        }
    }
    names.sort();
    names
        .into_iter()
        .map(|n| {
            let t = std::fs::read_to_string(root().join(&n)).unwrap();
            (n, t)
        })
        .collect()
}

/// The figures `scripts/figures.py` knows: name -> the chapter it writes into.
fn script_figures() -> BTreeMap<String, String> {
    let text = std::fs::read_to_string(root().join("scripts/figures.py")).unwrap();
    let body = text
        .split("FIGURES = {")
        .nth(1)
        .expect("FIGURES in scripts/figures.py");
    let body = &body[..body.find("\n}").unwrap()];
    let mut out = BTreeMap::new();
    for line in body.lines() {
        // `    "name": ("docs/chapter.md", fig_name,`
        let l = line.trim();
        if let Some(rest) = l.strip_prefix('"').filter(|r| r.contains("\": (\"")) {
            let name = &rest[..rest.find('"').unwrap()];
            let doc = l.split("(\"").nth(1).unwrap();
            out.insert(name.to_string(), doc[..doc.find('"').unwrap()].to_string());
        }
    }
    out
}

/// (name, chapter, the block's text) for every figure block in the pages: a line that is only
/// `<!-- figure:NAME -->` opens one, `<!-- /figure:NAME -->` closes it (a marker quoted in a sentence is not
/// one).
fn blocks(pages: &[(String, String)]) -> Vec<(String, String, String)> {
    let mut out = Vec::new();
    for (page, text) in pages {
        let mut open: Option<(String, Vec<&str>)> = None;
        for line in text.lines() {
            let l = line.trim();
            if let Some(name) = l
                .strip_prefix("<!-- figure:")
                .and_then(|r| r.strip_suffix(" -->"))
            {
                assert!(open.is_none(), "{page}: figure {name} opens inside another");
                open = Some((name.to_string(), Vec::new()));
            } else if let Some(name) = l
                .strip_prefix("<!-- /figure:")
                .and_then(|r| r.strip_suffix(" -->"))
            {
                let (n, body) = open
                    .take()
                    .unwrap_or_else(|| panic!("{page}: figure {name} closes without opening"));
                assert_eq!(n, name, "{page}: figure {n} closed as {name}");
                out.push((n, page.clone(), body.join("\n").trim().to_string()));
            } else if let Some((_, body)) = open.as_mut() {
                body.push(line);
            }
        }
        assert!(open.is_none(), "{page}: a figure block is never closed");
    }
    out
}

#[test]
fn every_figure_block_is_one_the_script_writes_and_every_one_is_placed() {
    let pages = pages();
    let known = script_figures();
    assert!(known.len() >= 10, "only {} figures read", known.len());
    let found = blocks(&pages);
    let mut seen = BTreeSet::new();
    for (name, page, body) in &found {
        let doc = known
            .get(name)
            .unwrap_or_else(|| panic!("{page}: figure {name} is not in scripts/figures.py"));
        assert_eq!(
            doc, page,
            "figure {name} is written into {doc}, placed in {page}"
        );
        assert!(seen.insert(name.clone()), "figure {name} placed twice");
        let stamp = format!("<sub>Measured by `scripts/figures.py {name}` on ");
        assert!(
            body.starts_with(&stamp),
            "{page}: figure {name} is empty or not the script's (run scripts/figures.py --write {name})"
        );
    }
    for name in known.keys() {
        assert!(
            seen.contains(name),
            "figure {name} has no markers in its chapter"
        );
    }
}

/// A heading's anchor as GitHub makes it: lower case, punctuation other than `-` and `_` dropped, spaces
/// as `-`.
fn slug(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || *c == ' ' || *c == '-' || *c == '_')
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

fn anchors(text: &str) -> BTreeSet<String> {
    let mut in_code = false;
    let mut out = BTreeSet::new();
    for line in text.lines() {
        if line.starts_with("```") {
            in_code = !in_code;
        }
        if !in_code && line.starts_with('#') {
            out.insert(slug(line.trim_start_matches('#')));
        }
    }
    out
}

/// Every `](target)` of a page, outside code blocks.
fn links(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut in_code = false;
    for line in text.lines() {
        if line.starts_with("```") {
            in_code = !in_code;
            continue;
        }
        if in_code {
            continue;
        }
        let mut rest = line;
        while let Some(i) = rest.find("](") {
            let after = &rest[i + 2..];
            let Some(j) = after.find(')') else { break };
            out.push(after[..j].to_string());
            rest = &after[j..];
        }
    }
    out
}

#[test]
fn links_between_the_pages_reach_their_files_and_headings() {
    let pages = pages();
    let texts: BTreeMap<String, &String> = pages.iter().map(|(n, t)| (n.clone(), t)).collect();
    let mut bad = Vec::new();
    for (page, text) in &pages {
        let dir = Path::new(page).parent().unwrap_or(Path::new(""));
        for link in links(text) {
            if link.contains("://") || link.starts_with("mailto:") {
                continue;
            }
            let (file, anchor) = match link.split_once('#') {
                Some((f, a)) => (f.to_string(), Some(a.to_string())),
                None => (link.clone(), None),
            };
            let target = if file.is_empty() {
                page.clone()
            } else {
                let p = dir.join(&file);
                // Normalise `docs/../README.md` to `README.md`.
                let mut parts: Vec<String> = Vec::new();
                for c in p.components() {
                    match c {
                        std::path::Component::ParentDir => {
                            parts.pop();
                        }
                        std::path::Component::Normal(s) => parts.push(s.to_string_lossy().into()),
                        _ => {}
                    }
                }
                parts.join("/")
            };
            if !root().join(&target).exists() {
                bad.push(format!("{page}: {link}: no file {target}"));
                continue;
            }
            if let (Some(a), Some(t)) = (anchor, texts.get(&target)) {
                if !anchors(t).contains(&a) {
                    bad.push(format!("{page}: {link}: no heading #{a} in {target}"));
                }
            }
        }
    }
    assert!(bad.is_empty(), "{bad:#?}");
}

/// Whether `line` holds a date, `20YY-MM-DD`.
fn has_date(line: &str) -> bool {
    let b = line.as_bytes();
    let digits = |r: std::ops::Range<usize>| b[r].iter().all(u8::is_ascii_digit);
    (0..b.len().saturating_sub(9)).any(|i| {
        b[i..].starts_with(b"20")
            && digits(i..i + 4)
            && b[i + 4] == b'-'
            && digits(i + 5..i + 7)
            && b[i + 7] == b'-'
            && digits(i + 8..i + 10)
    })
}

/// Whether `line` names a commit: `commit ` and at least 7 hexadecimal digits.
fn names_commit(line: &str) -> bool {
    line.match_indices("commit ").any(|(i, m)| {
        line[i + m.len()..]
            .chars()
            .take_while(char::is_ascii_hexdigit)
            .count()
            >= 7
    })
}

/// The lines of a page, numbered from 1, that carry a date outside a figure block without naming the
/// commit measured on the same line: dated history, not a measurement's stamp.
fn dated_history(text: &str) -> Vec<(usize, &str)> {
    let mut in_figure = false;
    let mut out = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let l = line.trim();
        if l.starts_with("<!-- figure:") {
            in_figure = true;
        } else if l.starts_with("<!-- /figure:") {
            in_figure = false;
        } else if !in_figure && has_date(line) && !names_commit(line) {
            out.push((n + 1, line));
        }
    }
    out
}

/// The chapters say what is, not how it came to be: a date in a chapter is a figure's stamp (inside a
/// figure block, or on the line naming the commit measured). Experiments, dead ends and dated
/// investigations go to docs/design/, changes to the CHANGELOG.
#[test]
fn the_chapters_carry_no_dated_history() {
    let mut bad = Vec::new();
    for (page, text) in pages() {
        if page == "CHANGELOG.md" || page.starts_with("docs/design/") {
            continue;
        }
        for (n, line) in dated_history(&text) {
            bad.push(format!("{page}:{n}: {line}"));
        }
    }
    assert!(
        bad.is_empty(),
        "dated lines outside figure stamps (move the history to docs/design/ or name the commit \
         measured on the date's line):\n{}",
        bad.join("\n")
    );
}

#[test]
fn the_pages_name_no_tracker_issue() {
    let mut bad = Vec::new();
    for (page, text) in pages() {
        for (n, line) in text.lines().enumerate() {
            let l = line.to_lowercase();
            let mut rest = l.as_str();
            while let Some(i) = rest.find("issue") {
                let after = rest[i + 5..].trim_start_matches([' ', '#', 's']);
                if after.starts_with(|c: char| c.is_ascii_digit()) {
                    bad.push(format!("{page}:{}: {line}", n + 1));
                    break;
                }
                rest = &rest[i + 5..];
            }
        }
    }
    assert!(bad.is_empty(), "{bad:#?}");
}

/// The repository paths a page names (`src/...`, `tests/...`, `shaders/...`, `scripts/...`, in text or as
/// `../` links), less globs and placeholders (`tests/*.rs`, `fuzz/corpus/TARGET`).
fn repo_paths(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let path_char = |c: char| c.is_ascii_alphanumeric() || "_-./".contains(c);
    for start in [
        "src/",
        "tests/",
        "shaders/",
        "scripts/",
        "benches/",
        "examples/",
        "ros/",
    ] {
        let mut from = 0;
        while let Some(k) = text[from..].find(start) {
            let s = from + k;
            from = s + start.len();
            let before = text[..s].chars().last();
            if before.is_some_and(path_char) && !text[..s].ends_with("../") {
                continue;
            }
            let end = text[s..]
                .find(|c: char| !path_char(c))
                .map_or(text.len(), |e| s + e);
            let p = text[s..end].trim_end_matches(['.', ',', ':']);
            let next = text[end..].chars().next();
            let glob = next.is_some_and(|c| c == '*' || c == '{' || c == '<')
                || p.split('/').any(|seg| {
                    seg.chars().any(|c| c.is_ascii_uppercase())
                        && seg
                            .chars()
                            .all(|c| c.is_ascii_uppercase() || c == '_' || c == '.')
                });
            if !glob && p.len() > start.len() {
                out.push(p.to_string());
            }
        }
    }
    out
}

/// The library's module paths a page names in code spans: `ogm_corners::a::b`, `crate::a::b`, or `a::b`
/// where `a` is one of the library's top-level modules.
fn module_paths(text: &str, top: &BTreeSet<String>) -> Vec<String> {
    let mut out = Vec::new();
    for (i, span) in text.split('`').enumerate() {
        if i % 2 == 0 || span.contains(' ') {
            continue;
        }
        let p = span.trim_end_matches("()");
        let p = p
            .strip_prefix("ogm_corners::")
            .or_else(|| p.strip_prefix("crate::"))
            .unwrap_or(p);
        let first = p.split("::").next().unwrap_or("");
        if p.contains("::")
            && top.contains(first)
            && p.split("::")
                .all(|s| !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_'))
        {
            out.push(p.to_string());
        }
    }
    out
}

/// Every `.rs` file of `src/` as one text, read once for all the paths the pages name (the walk is
/// the layering check's).
fn all_sources() -> &'static str {
    static ALL: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    ALL.get_or_init(|| {
        let src = root().join("src");
        let mut files = Vec::new();
        crate::layering::sources(&src, &src, &mut files);
        files
            .iter()
            .map(|f| std::fs::read_to_string(src.join(f)).unwrap())
            .collect::<Vec<_>>()
            .join("\n")
    })
}

/// Whether `path` (`a::b::Item::method`) names a public module path of the library and an item in it:
/// each module declared `pub mod` in its parent, the first other segment defined or re-exported in the
/// last module's file, any further one (a method, a variant, a field) defined somewhere in `src/`.
fn module_path_exists(path: &str) -> Result<(), String> {
    let src = root().join("src");
    let read = |f: &Path| std::fs::read_to_string(f).unwrap_or_default();
    let segs: Vec<&str> = path.split("::").collect();
    let (mut file, mut dir) = (src.join("lib.rs"), src.clone());
    let mut k = 0;
    while k < segs.len() {
        let s = segs[k];
        let declared = read(&file).lines().any(|l| {
            let l = l.trim();
            l == format!("pub mod {s};") || l == format!("pub mod {s} {{")
        });
        if !declared {
            break;
        }
        let (a, b) = (dir.join(format!("{s}.rs")), dir.join(s).join("mod.rs"));
        file = if a.is_file() { a } else { b };
        dir = dir.join(s);
        k += 1;
    }
    if k == 0 {
        return Err(format!("{}: not a public module", segs[0]));
    }
    let Some(item) = segs.get(k) else {
        return Ok(());
    };
    let text = read(&file);
    // Items a page names are public ones: `pub fn`, not `pub(crate) fn`; members need only exist.
    let defined_as = |t: &str, name: &str, vis: &str| {
        [
            "fn", "struct", "enum", "trait", "type", "const", "static", "mod",
        ]
        .iter()
        .any(|kw| {
            ["(", " ", "<", ";", ":"]
                .iter()
                .any(|end| t.contains(&format!("{vis}{kw} {name}{end}")))
        })
    };
    // Re-exported: a name a `pub use` statement (one line or several) ends a path with.
    let mut uses = String::new();
    let mut inside = false;
    for l in text.lines() {
        if l.trim_start().starts_with("pub use") || inside {
            uses.push_str(l);
            uses.push('\n');
            inside = !l.contains(';');
        }
    }
    let leaves = uses.replace("pub use", " ");
    let reexported = leaves
        .split(|c: char| !(c.is_ascii_alphanumeric() || c == '_' || c == ':'))
        .any(|w| w.rsplit("::").next() == Some(*item) && !w.ends_with("::"));
    let defined = |t: &str, name: &str| defined_as(t, name, "");
    if !defined_as(&text, item, "pub ") && !reexported {
        return Err(format!(
            "{item}: not in {}",
            file.strip_prefix(root()).unwrap().display()
        ));
    }
    for rest in &segs[k + 1..] {
        let all_src = all_sources();
        let member = defined(all_src, rest)
            || all_src.contains(&format!("pub {rest}:"))
            || all_src.lines().any(|l| {
                l.trim().starts_with(&format!("{rest},"))
                    || l.trim().starts_with(&format!("{rest} {{"))
                    || l.trim().starts_with(&format!("{rest}("))
            });
        if !member {
            return Err(format!("{rest}: defined nowhere in src/"));
        }
    }
    Ok(())
}

#[test]
fn the_files_and_module_paths_the_pages_name_exist() {
    let lib = std::fs::read_to_string(root().join("src/lib.rs")).unwrap();
    let top: BTreeSet<String> = lib
        .lines()
        .filter_map(|l| l.trim().strip_prefix("pub mod "))
        .map(|m| m.trim_end_matches(';').to_string())
        .collect();
    assert!(top.contains("merge") && top.contains("map"), "{top:?}");
    let mut bad = Vec::new();
    let (mut files, mut paths) = (0, 0);
    // The CHANGELOG is history: it names files and paths as they were.
    for (page, text) in pages().iter().filter(|(p, _)| p != "CHANGELOG.md") {
        for p in repo_paths(text) {
            files += 1;
            if !root().join(&p).exists() {
                bad.push(format!("{page}: no file {p}"));
            }
        }
        for p in module_paths(text, &top) {
            paths += 1;
            if let Err(e) = module_path_exists(&p) {
                bad.push(format!("{page}: `{p}`: {e}"));
            }
        }
    }
    assert!(
        files > 50 && paths > 20,
        "only {files} files and {paths} module paths read"
    );
    assert!(
        bad.is_empty(),
        "{} paths that do not exist: {bad:#?}",
        bad.len()
    );
}

#[test]
fn the_checks_see_what_they_look_for() {
    assert_eq!(
        slug(" Merging many maps (`merge A B C ...`, `merge-eval --global`)"),
        "merging-many-maps-merge-a-b-c--merge-eval---global"
    );
    assert_eq!(
        links("see [a](b.md#c) and [d](https://e)"),
        ["b.md#c", "https://e"]
    );
    let b = blocks(&[(
        "x.md".into(),
        "a\n<!-- figure:f -->\n<sub>Measured by\n<!-- /figure:f -->\n".into(),
    )]);
    assert_eq!(b, [("f".into(), "x.md".into(), "<sub>Measured by".into())]);
    assert_eq!(
        repo_paths(
            "see `src/map/yaml.rs`, [x](../tests/cli/commands.rs) and python/src/x.rs, not tests/*.rs."
        ),
        ["src/map/yaml.rs", "tests/cli/commands.rs"]
    );
    let top = BTreeSet::from(["merge".to_string()]);
    assert_eq!(
        module_paths(
            "`merge::align::align()` `ogm_corners::merge::X` `map::a` `merge a b`",
            &top
        ),
        ["merge::align::align", "merge::X"]
    );
    assert!(module_path_exists("merge::align::align_with").is_ok());
    assert!(module_path_exists("merge::global::merged::merge_maps").is_err());
    assert!(module_path_exists("merge::compose::resample").is_err());
    let page = "a\nrun on 2026-12-03, before the fix\n(2026-12-04, commit b00f143, H200)\n\
                <!-- figure:f -->\n<sub>Measured on 2026-12-07</sub>\n<!-- /figure:f -->\n\
                2026-12-05 commit 12ab\nversion 2026-1-02\n";
    assert_eq!(
        dated_history(page),
        [
            (2, "run on 2026-12-03, before the fix"),
            (7, "2026-12-05 commit 12ab")
        ]
    );
}
