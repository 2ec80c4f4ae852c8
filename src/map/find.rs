//! Finding the maps in folders, for batch runs: each real folder once, unreadable entries reported, never
//! fatal.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use super::{MapYaml, MAX_YAML_BYTES};
use crate::support::files::{self, FileId};
use crate::support::marks::{self, Written};

/// What [`find_maps`] found.
#[derive(Debug, Default)]
pub struct FoundMaps {
    /// The maps, files as given and then each folder's in path order.
    pub maps: Vec<PathBuf>,
    /// Things left out on purpose, for information: yaml files that are not maps, links back into a
    /// folder already searched.
    pub notes: Vec<String>,
    /// Entries that could not be read (an unreadable folder or yaml, a fifo named like a map, a folder
    /// with no map): skipped so the rest is processed, but the run should end with an error.
    pub problems: Vec<String>,
}

/// The maps named by `inputs`: files as given, and for each folder (searched recursively, in path order,
/// hidden entries left out, each real folder once however many links lead to it) every ROS map yaml plus
/// every PGM/PNG image that no yaml there names. A yaml that is not a map (ROS packages keep other yaml
/// files beside their maps) is left out with a note, and so are the tool's own outputs (merged maps,
/// pictures: [`crate::support::marks`]). A map yaml that cannot be read or parsed is a problem, and the image it
/// names is not used alone. Unreadable entries are reported in [`FoundMaps::problems`] and skipped; they
/// never stop the search.
pub fn find_maps(inputs: &[PathBuf]) -> FoundMaps {
    let mut found = FoundMaps::default();
    let mut seen_dirs: HashSet<FileId> = HashSet::new();
    let mut seen_files: HashSet<FileId> = HashSet::new();
    for input in inputs {
        if !input.is_dir() {
            found.maps.push(input.clone());
            continue;
        }
        let before = found.maps.len();
        // A folder named twice, or inside one named before, was searched already.
        if FileId::of(input).is_some_and(|id| seen_dirs.contains(&id)) {
            found
                .notes
                .push(format!("{}: searched already", input.display()));
            continue;
        }
        let (files, unreadable) = walk(input, &mut seen_dirs, &mut seen_files, &mut found);
        let ext = |p: &Path| {
            p.extension()
                .and_then(|e| e.to_str())
                .map(str::to_ascii_lowercase)
                .unwrap_or_default()
        };
        // The images the yamls name (or meant to name), compared as file identities (links and
        // spellings alike): never read as bare images.
        let mut named: HashSet<FileId> = unreadable
            .iter()
            .filter(|p| super::is_yaml(p))
            .flat_map(|y| same_stem_images(y))
            .filter_map(|p| FileId::of(&p))
            .collect();
        let mut own = OwnOutputs::default();
        for y in files.iter().filter(|p| super::is_yaml(p)) {
            let dir = y.parent().unwrap_or(Path::new(""));
            match read_map_yaml(y) {
                YamlFound::Map { image, mark } => {
                    named.extend(FileId::of(&dir.join(image)));
                    match mark {
                        Some(kind) => own.count(y, kind),
                        None => found.maps.push(y.clone()),
                    }
                }
                YamlFound::NotAMap(why) => found
                    .notes
                    .push(format!("skipped {}: not a map yaml: {why}", y.display())),
                // A broken or unreadable map yaml is an error, and the image it names (or, when it
                // cannot say, the image of its own name beside it) is not read as a bare image either:
                // that would detect with the wrong thresholds and place the map with no georeference.
                YamlFound::Broken { image, problem } => {
                    for p in image
                        .map(|i| dir.join(i))
                        .into_iter()
                        .chain(same_stem_images(y))
                    {
                        named.extend(FileId::of(&p));
                    }
                    found.problems.push(format!("skipped {problem}"));
                }
            }
        }
        for p in &files {
            if !matches!(ext(p).as_str(), "pgm" | "png")
                || FileId::of(p).is_some_and(|id| named.contains(&id))
            {
                continue;
            }
            match marks::written_by_tool(p) {
                Some(kind) => own.count(p, kind),
                None => found.maps.push(p.clone()),
            }
        }
        found.notes.extend(own.note(input));
        if found.maps.len() == before {
            found.problems.push(format!(
                "{}: no maps in this folder (looked for .yaml, .pgm and .png files)",
                input.display()
            ));
        }
    }
    found
}

/// What a yaml in a searched folder is.
enum YamlFound {
    /// A map yaml naming this image, and the tool's mark when the tool wrote it (a merged map).
    Map {
        image: String,
        mark: Option<Written>,
    },
    /// Some other yaml (ROS packages keep parameter files beside their maps), with why.
    NotAMap(String),
    /// A map yaml that cannot be read or parsed, with the image it means when that can be made out, and
    /// the problem (naming the file).
    Broken {
        image: Option<String>,
        problem: String,
    },
}

fn read_map_yaml(y: &Path) -> YamlFound {
    let text = match files::read_small_text(y, MAX_YAML_BYTES, "a map yaml") {
        Ok(t) => t,
        Err(e) if e.to_string().contains("too large") => return YamlFound::NotAMap(e.to_string()),
        Err(e) => {
            return YamlFound::Broken {
                image: None,
                problem: e.to_string(),
            }
        }
    };
    match MapYaml::parse(&text) {
        // The mark from the text already read, not the file again.
        Ok(meta) => YamlFound::Map {
            image: meta.image,
            mark: marks::mark_in(text.as_bytes()),
        },
        Err(why) => match MapYaml::meant_image(&text) {
            Some(image) => YamlFound::Broken {
                image: Some(image),
                problem: format!("{}: {why}", y.display()),
            },
            None => YamlFound::NotAMap(why),
        },
    }
}

/// `NAME.pgm` and `NAME.png` beside `NAME.yaml`: the images a yaml that cannot be read most likely names.
fn same_stem_images(y: &Path) -> impl Iterator<Item = PathBuf> + '_ {
    ["pgm", "png", "PGM", "PNG"]
        .into_iter()
        .map(move |e| y.with_extension(e))
}

/// The tool's own outputs met in a folder (a merged map, report pictures, overlays): left out, and
/// counted for one note.
#[derive(Default)]
struct OwnOutputs {
    count: usize,
    first: Option<(PathBuf, Written)>,
}

impl OwnOutputs {
    /// `p`, which the tool wrote as `kind`, left out.
    fn count(&mut self, p: &Path, kind: Written) {
        self.count += 1;
        self.first.get_or_insert_with(|| (p.to_path_buf(), kind));
    }

    fn note(&self, dir: &Path) -> Option<String> {
        let (first, kind) = self.first.as_ref()?;
        Some(format!(
            "{}: left out {} {} that ogm-corners wrote (merged maps, pictures), such as {} ({}); name a \
             file to use it as a map",
            dir.display(),
            self.count,
            if self.count == 1 { "file" } else { "files" },
            first.display(),
            kind.describe()
        ))
    }
}

/// The regular files under `root`, sorted, each real folder and file visited once; and the entries
/// named like maps that are no regular file or cannot be read (reported in `found`).
fn walk(
    root: &Path,
    seen_dirs: &mut HashSet<FileId>,
    seen_files: &mut HashSet<FileId>,
    found: &mut FoundMaps,
) -> (Vec<PathBuf>, Vec<PathBuf>) {
    let mut files = Vec::new();
    let mut unreadable = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        let Some(id) = FileId::of(&dir) else {
            found
                .problems
                .push(format!("skipped {}: cannot read the folder", dir.display()));
            continue;
        };
        if !seen_dirs.insert(id) {
            if dir != root {
                found.notes.push(format!(
                    "skipped {}: a link to a folder already searched",
                    dir.display()
                ));
            }
            continue;
        }
        let entries = match std::fs::read_dir(&dir) {
            Ok(e) => e,
            Err(e) => {
                found.problems.push(format!(
                    "skipped {}: cannot list the folder: {e}",
                    dir.display()
                ));
                continue;
            }
        };
        for entry in entries {
            let p = match entry {
                Ok(e) => e.path(),
                Err(e) => {
                    found
                        .problems
                        .push(format!("skipped an entry of {}: {e}", dir.display()));
                    continue;
                }
            };
            let hidden = p
                .file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with('.'));
            if hidden {
                continue;
            }
            let is_map_name = p
                .extension()
                .and_then(|e| e.to_str())
                .map(str::to_ascii_lowercase)
                .is_some_and(|e| matches!(e.as_str(), "yaml" | "yml" | "pgm" | "png"));
            match std::fs::metadata(&p) {
                Ok(m) if m.is_dir() => stack.push(p),
                Ok(m) if m.is_file() => {
                    if seen_files.insert(FileId::from_meta(&p, &m)) {
                        files.push(p);
                    }
                }
                Ok(m) if is_map_name => {
                    found.problems.push(format!(
                        "skipped {}: not a regular file ({})",
                        p.display(),
                        files::kind_of(&m)
                    ));
                    unreadable.push(p);
                }
                Ok(_) => {}
                Err(e) if is_map_name => {
                    found
                        .problems
                        .push(format!("skipped {}: cannot read: {e}", p.display()));
                    unreadable.push(p);
                }
                // A broken link or unreadable entry that is no map is none of our business.
                Err(_) => {}
            }
        }
    }
    files.sort();
    (files, unreadable)
}

/// A file name for each map: its stem, or its folder for ROS's usual `map.yaml`, made unique with `-2`,
/// `-3`... in input order.
pub fn output_names(maps: &[PathBuf]) -> Vec<String> {
    let mut seen = HashSet::new();
    maps.iter()
        .map(|p| {
            let base = map_name(p);
            let mut name = base.clone();
            let mut n = 1;
            while !seen.insert(name.clone()) {
                n += 1;
                name = format!("{base}-{n}");
            }
            name
        })
        .collect()
}

/// Path components too generic to name a map by: ROS packages keep `map.yaml` in a `map` or `maps` folder.
const GENERIC_NAMES: [&str; 2] = ["map", "maps"];

fn is_generic(s: &str) -> bool {
    GENERIC_NAMES.iter().any(|g| g.eq_ignore_ascii_case(s))
}

/// A short name for a map file: its first distinctive path component, from the file up. The stem, unless
/// it is a generic `map`; then the nearest folder that is not `map` or `maps` (TurtleBot3's
/// `turtlebot3_navigation2/map/map.yaml` is `turtlebot3_navigation2`). A relative path is read from the
/// current folder, so `map.yaml` alone is named by the folder it is in.
pub fn map_name(p: &Path) -> String {
    let stem = p.file_stem().and_then(|s| s.to_str()).unwrap_or("map");
    if !is_generic(stem) {
        return stem.to_string();
    }
    let parent = p.parent().unwrap_or(Path::new(""));
    let parent = if parent.as_os_str().is_empty() {
        Path::new(".")
    } else {
        parent
    };
    // Canonical, so `..` and links name the folder the map is really in.
    let dir = std::fs::canonicalize(parent)
        .or_else(|_| std::path::absolute(parent))
        .unwrap_or_else(|_| parent.to_path_buf());
    dir.components()
        .rev()
        .filter_map(|c| match c {
            std::path::Component::Normal(s) => s.to_str(),
            _ => None,
        })
        .find(|s| !is_generic(s))
        .unwrap_or(stem)
        .to_string()
}

#[cfg(test)]
mod name_tests {
    use super::*;

    #[test]
    fn maps_are_named_by_their_first_distinctive_component() {
        let n = |s: &str| map_name(Path::new(s));
        assert_eq!(
            n("/x/turtlebot3_navigation2/map/map.yaml"),
            "turtlebot3_navigation2"
        );
        assert_eq!(n("/x/brsu-c069/map.yaml"), "brsu-c069");
        assert_eq!(n("/x/maps/tiz_01/map.yaml"), "tiz_01");
        assert_eq!(n("/x/maps/willow-full.pgm"), "willow-full");
        assert_eq!(n("/x/Maps/MAP.pgm"), "x");
        let dir = tempfile::tempdir().unwrap();
        let inner = dir.path().join("lab_7").join("maps");
        std::fs::create_dir_all(&inner).unwrap();
        assert_eq!(
            map_name(&inner.join("..").join("maps").join("map.yaml")),
            "lab_7"
        );
        let names = output_names(&[
            PathBuf::from("/a/site/map/map.yaml"),
            PathBuf::from("/b/site/maps/map.pgm"),
        ]);
        assert_eq!(names, ["site", "site-2"]);
    }
}
