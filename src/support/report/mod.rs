//! Static HTML reports (`--html DIR` of `compare`, `eval`, `merge-eval` and `merge` of many maps): one
//! self-contained page, `DIR/index.html`, with inline CSS and a little vanilla JavaScript (tables sorted by
//! a click on a column), and PNG pictures beside it. No server, no network: it opens from `file://`.
//! This file holds the page's parts (tables, figures, legends); `html.rs`, the markup, its CSS and the
//! table sorter.
//!
//! Pictures are written as they are made (so a report of hundreds of pairs holds one picture at a time),
//! into a hidden staging folder inside the report's folder; the page is written last, and only then are
//! the pictures and the page moved into the folder (the page last) and the previous report's pictures that
//! the new page does not show removed. A run stopped or failed before then leaves the folder as it was
//! (the previous report whole) and no staging folder; files in the folder that are not a report's are
//! never touched.

mod html;

use std::path::{Path, PathBuf};

use image::RgbImage;

use crate::support::error::Result;
use crate::support::files;

pub use html::escape;

/// The page's file in a report folder.
pub const INDEX: &str = "index.html";

/// A report being written into a folder.
pub struct Report {
    dir: PathBuf,
    /// Where the pictures and the page are written before they are moved into `dir`.
    staging: files::StagingDir,
    title: String,
    blocks: Vec<Block>,
}

/// A report written into its staging folder, not yet moved into its folder ([`Staged::commit`]): how a
/// command commits its other outputs only once the report could be written, and the report after them.
pub struct Staged {
    dir: PathBuf,
    staging: files::StagingDir,
    pictures: Vec<String>,
}

/// One part of the page, in order.
enum Block {
    Heading(String),
    Text(String),
    Table(Table),
    Figures(Vec<Figure>, u32),
    Legend(Vec<(String, [u8; 3])>),
}

/// A picture on the page.
pub struct Figure {
    /// Its file, relative to the page.
    pub src: String,
    /// Caption lines under it (the first in bold).
    pub caption: Vec<String>,
    /// Anchor a table row links to.
    pub id: Option<String>,
    /// Size, pixels (the page reserves it before the picture loads).
    pub size: (u32, u32),
    /// A class for the frame: `bad` (red), `warn` (amber) or `good` (green).
    pub class: Option<&'static str>,
}

/// A table, sortable by any column in the browser.
pub struct Table {
    id: String,
    caption: String,
    columns: Vec<(String, bool)>,
    rows: Vec<Row>,
}

/// A table row.
pub struct Row {
    cells: Vec<Cell>,
    class: Option<&'static str>,
}

/// A table cell: its text, and the key it sorts by when that is not the text (numbers shown rounded or
/// with units, missing values).
#[derive(Clone, Debug)]
pub struct Cell {
    text: String,
    key: Option<String>,
    class: Option<&'static str>,
    link: Option<String>,
}

impl Cell {
    /// Text, sorted as text.
    pub fn text(s: impl Into<String>) -> Self {
        Cell {
            text: s.into(),
            key: None,
            class: None,
            link: None,
        }
    }

    /// An integer.
    pub fn int(n: impl Into<i128>) -> Self {
        Cell::text(n.into().to_string())
    }

    /// A number shown with `decimals` places, sorted by its full value.
    pub fn num(v: f64, decimals: usize) -> Self {
        Cell {
            key: Some(format!("{v}")),
            ..Cell::text(format!("{v:.decimals$}"))
        }
    }

    /// A number or `-` (sorted last).
    pub fn opt(v: Option<f64>, decimals: usize) -> Self {
        match v {
            Some(v) if v.is_finite() => Cell::num(v, decimals),
            _ => Cell {
                key: Some(String::new()),
                ..Cell::text("-")
            },
        }
    }

    /// Shown as `text`, sorted by `key`.
    pub fn keyed(text: impl Into<String>, key: f64) -> Self {
        Cell {
            key: Some(format!("{key}")),
            ..Cell::text(text)
        }
    }

    /// With a class: `bad` (red), `good` (green), `warn` (amber).
    pub fn class(self, class: &'static str) -> Self {
        Cell {
            class: Some(class),
            ..self
        }
    }

    /// A link (an anchor on the page, `#id`, or a file beside it).
    pub fn link(self, href: impl Into<String>) -> Self {
        Cell {
            link: Some(href.into()),
            ..self
        }
    }
}

impl Table {
    /// A table `id` (unique on the page) with a caption and columns `(label, numeric)`.
    pub fn new(id: &str, caption: impl Into<String>, columns: &[(&str, bool)]) -> Self {
        Table {
            id: id.to_string(),
            caption: caption.into(),
            columns: columns.iter().map(|&(l, n)| (l.to_string(), n)).collect(),
            rows: Vec::new(),
        }
    }

    /// Adds a row (one cell a column).
    pub fn row(&mut self, cells: Vec<Cell>) {
        self.row_with(cells, None);
    }

    /// Adds a row highlighted with `class` (`bad`, `good`, `warn`).
    pub fn row_with(&mut self, cells: Vec<Cell>, class: Option<&'static str>) {
        debug_assert_eq!(cells.len(), self.columns.len(), "table {}", self.id);
        self.rows.push(Row { cells, class });
    }

    /// Rows so far.
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// Whether it has no rows.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }
}

impl Report {
    /// A report titled `title` written into `dir` (made when missing).
    pub fn create(dir: &Path, title: impl Into<String>) -> Result<Self> {
        files::create_dir(dir)?;
        Ok(Report {
            dir: dir.to_path_buf(),
            staging: files::StagingDir::new_in(dir)?,
            title: title.into(),
            blocks: Vec::new(),
        })
    }

    /// The page's path.
    pub fn index(&self) -> PathBuf {
        self.dir.join(INDEX)
    }

    /// A section heading.
    pub fn heading(&mut self, text: impl Into<String>) {
        self.blocks.push(Block::Heading(text.into()));
    }

    /// A paragraph of text.
    pub fn text(&mut self, text: impl Into<String>) {
        self.blocks.push(Block::Text(text.into()));
    }

    /// A table.
    pub fn table(&mut self, table: Table) {
        self.blocks.push(Block::Table(table));
    }

    /// A legend of colour swatches (the entries the pictures' legends take, [`crate::support::plot::draw_legend`]).
    pub fn legend<S: AsRef<str>>(&mut self, entries: &[(S, image::Rgb<u8>)]) {
        self.blocks.push(Block::Legend(
            entries
                .iter()
                .map(|(l, c)| (l.as_ref().to_string(), c.0))
                .collect(),
        ));
    }

    /// Writes `picture` as `name` (a plain file name, `.png`) beside the page now, and returns it as a
    /// figure to place with [`Report::figures`].
    pub fn picture(
        &mut self,
        name: &str,
        picture: &RgbImage,
        caption: Vec<String>,
    ) -> Result<Figure> {
        files::write_png(&self.staging.path().join(name), picture)?;
        Ok(Figure {
            src: name.to_string(),
            caption,
            id: None,
            size: (picture.width(), picture.height()),
            class: None,
        })
    }

    /// A grid of figures, as many a row as fit at 360 pixels or more each.
    pub fn figures(&mut self, figures: Vec<Figure>) {
        self.figures_at(figures, 360);
    }

    /// A grid of figures, as many a row as fit at `min_width` pixels or more each (wide contact sheets).
    pub fn figures_at(&mut self, figures: Vec<Figure>, min_width: u32) {
        if !figures.is_empty() {
            self.blocks.push(Block::Figures(figures, min_width));
        }
    }

    /// Writes the page and moves the report into its folder ([`Report::stage`], [`Staged::commit`]);
    /// returns the page's path.
    pub fn finish(self) -> Result<PathBuf> {
        self.stage()?.commit()
    }

    /// Writes the page into the staging folder, beside the pictures.
    pub fn stage(self) -> Result<Staged> {
        let page = html::page(&self.title, &self.blocks);
        let staged = self.staging.path().join(INDEX);
        files::write_atomic(&staged, |out| out.write_all(page.as_bytes()))?;
        Ok(Staged {
            pictures: pictures_of(&page),
            dir: self.dir,
            staging: self.staging,
        })
    }
}

impl Staged {
    /// Moves the pictures, then the page, into the report's folder, and removes the pictures of the
    /// report it replaces that the new page does not show; returns the page's path.
    pub fn commit(self) -> Result<PathBuf> {
        let index = self.dir.join(INDEX);
        let old: Vec<String> = std::fs::read_to_string(&index)
            .map(|page| pictures_of(&page))
            .unwrap_or_default();
        let from = self.staging.path();
        let mut names: Vec<std::ffi::OsString> = std::fs::read_dir(from)
            .map_err(|e| crate::Error::output(from, e))?
            .filter_map(|e| e.ok().map(|e| e.file_name()))
            .filter(|n| n != INDEX)
            .collect();
        names.sort();
        names.push(INDEX.into());
        for name in names {
            let target = self.dir.join(&name);
            std::fs::rename(from.join(&name), &target)
                .map_err(|e| crate::Error::output(&target, e))?;
        }
        for stale in old.iter().filter(|p| !self.pictures.contains(p)) {
            let _ = std::fs::remove_file(self.dir.join(stale));
        }
        Ok(index)
    }
}

/// The pictures a page shows: its `<img src="...">` names that are plain file names (no folder), as
/// [`Report::picture`] writes them.
fn pictures_of(page: &str) -> Vec<String> {
    page.split("<img src=\"")
        .skip(1)
        .filter_map(|rest| rest.split('"').next())
        .filter(|name| {
            !name.is_empty()
                && !name.contains(['/', '\\'])
                && !name.starts_with('.')
                && name.ends_with(".png")
        })
        .map(str::to_string)
        .collect()
}

/// A picture's file name for a label: letters, digits, `-` and `_` kept, anything else `_`, with `n` (an
/// index unique in the report) in front so that labels that differ only in dropped characters stay apart.
pub fn file_name(n: usize, label: &str, suffix: &str) -> String {
    let clean: String = label
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .take(60)
        .collect();
    format!("{n:03}-{clean}{suffix}.png")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_page_holds_tables_figures_and_escaped_text() {
        let dir = tempfile::tempdir().unwrap();
        let mut r = Report::create(dir.path(), "a <report> & more").unwrap();
        let mut t = Table::new("t", "caption", &[("name", false), ("value", true)]);
        t.row(vec![Cell::text("<b>"), Cell::num(1.26, 1)]);
        t.row_with(vec![Cell::text("x"), Cell::opt(None, 1)], Some("bad"));
        assert_eq!(t.len(), 2);
        r.table(t);
        let pic = RgbImage::from_pixel(3, 2, image::Rgb([1, 2, 3]));
        let f = r.picture("p.png", &pic, vec!["first".into()]).unwrap();
        assert_eq!(f.size, (3, 2));
        r.figures(vec![f]);
        r.legend(&[("walls", image::Rgb([0, 0, 0]))]);
        let path = r.finish().unwrap();
        let page = std::fs::read_to_string(&path).unwrap();
        assert!(page.contains("<h1>a &lt;report&gt; &amp; more</h1>"));
        assert!(page.contains(r#"<table class="report" id="t" data-rows="2">"#));
        assert!(page.contains(r#"<td data-key="1.26">1.3</td>"#));
        assert!(page.contains(r#"<tr class="bad"><td class="t">x</td><td data-key="">-</td></tr>"#));
        assert!(page.contains("&lt;b&gt;"));
        assert!(page.contains(r#"<img src="p.png""#));
        assert!(page.contains("rgb(0,0,0)"));
        // No network: nothing is fetched from anywhere but the folder.
        assert!(!page.contains("http://") && !page.contains("https://"));
        assert!(dir.path().join("p.png").is_file());
    }

    #[test]
    fn file_names_are_plain_and_unique() {
        assert_eq!(file_name(7, "a b/c.yaml", "-x"), "007-a_b_c_yaml-x.png");
        assert_ne!(file_name(1, "a/b", ""), file_name(2, "a/b", ""));
    }
}
