//! The `eval --html` page: the repeatability table, its plots and each map's keypoints per detector; or,
//! with `--annotations`, the recall table and each annotated map's marked points against the keypoints.

use std::path::{Path, PathBuf};

use image::RgbImage;

use crate::measure::detection::EvalRecord;
use crate::support::error::Result;
use crate::support::report::{file_name, Figure, Report};

/// The picture of map `i` named `name` on the page: its keypoints per detector (`marked`: false) or its
/// marked points ([`crate::measure::detection::annotations::marked_sheet`]).
pub fn picture_file(i: usize, name: &str, marked: bool) -> String {
    file_name(i, name, if marked { "-marked" } else { "-keypoints" })
}

/// Every picture file a page for maps `names` may write: one per map, and the plots (repeatability only).
pub fn picture_files(names: &[String], marked: bool) -> Vec<String> {
    let plots = crate::measure::detection::PLOT_FILES
        .iter()
        .filter(|_| !marked);
    names
        .iter()
        .enumerate()
        .map(|(i, n)| picture_file(i, n, marked))
        .chain(plots.map(|f| f.to_string()))
        .collect()
}

/// The rows as the `--html` page's table (`id="eval"`): repeatability in percent, missing when no trial
/// had keypoints in the shared region.
pub fn repeatability_table(rows: &[EvalRecord]) -> crate::support::report::Table {
    use crate::support::report::{Cell, Table};
    let mut t = Table::new(
        "eval",
        "Repeatability: keypoints found again after a known change of the map, within the tolerance (mean over the trials)",
        &[
            ("map", false),
            ("detector", false),
            ("condition", false),
            ("level", true),
            ("repeatability %", true),
            ("trials", true),
        ],
    );
    for r in rows {
        t.row(vec![
            Cell::text(&r.map),
            Cell::text(r.detector),
            Cell::text(r.condition),
            Cell::num(r.level, 3),
            Cell::opt(r.repeatability.map(|v| 100.0 * v), 1),
            Cell::int(r.trials),
        ]);
    }
    t
}

/// An `eval --html` page being written: each map's picture written as the map is done.
pub struct EvalPage {
    report: Report,
    figures: Vec<Figure>,
}

impl EvalPage {
    /// A page written into `dir` (made now, so that a bad folder is found before the work).
    pub fn create(dir: &Path) -> Result<Self> {
        Ok(EvalPage {
            report: Report::create(dir, "ogm-corners eval")?,
            figures: Vec::new(),
        })
    }

    /// Adds map `i`'s picture ([`picture_file`]), captioned with its name and path.
    pub fn add_map(
        &mut self,
        i: usize,
        name: &str,
        path: &Path,
        picture: &RgbImage,
        marked: bool,
    ) -> Result<()> {
        let caption = vec![name.to_string(), path.display().to_string()];
        let file = picture_file(i, name, marked);
        self.figures
            .push(self.report.picture(&file, picture, caption)?);
        Ok(())
    }

    /// Writes the repeatability page (`about`: a line on the run) and returns its path.
    pub fn finish_repeatability(mut self, rows: &[EvalRecord], about: &str) -> Result<PathBuf> {
        let r = &mut self.report;
        r.text(format!("{about} Click a column to sort."));
        r.table(repeatability_table(rows));
        r.heading("Repeatability against noise and rotation, averaged over the maps");
        let plots = crate::measure::detection::repeatability_plots(rows)
            .into_iter()
            .map(|(file, picture)| r.picture(file, &picture, vec![file.to_string()]))
            .collect::<Result<Vec<_>>>()?;
        r.figures_at(plots, 600);
        r.heading("Each detector's keypoints on each map");
        r.legend(&crate::measure::compare::rule_legend());
        r.figures_at(self.figures, 900);
        self.report.finish()
    }

    /// Writes the recall page for the marked points of `source` and returns its path.
    pub fn finish_recall(
        mut self,
        rows: &[crate::measure::detection::annotations::RecallRecord],
        source: &Path,
    ) -> Result<PathBuf> {
        let r = &mut self.report;
        r.text(format!(
            "Marked points from {}; rows per map, then pooled over the maps (green). Click a column to sort.",
            source.display()
        ));
        r.table(crate::measure::detection::annotations::html_table(rows));
        r.heading(
            "The marked points (green rings) against the paper's and the robust detector's keypoints",
        );
        r.legend(&crate::measure::compare::rule_legend());
        r.figures_at(self.figures, 900);
        self.report.finish()
    }
}
