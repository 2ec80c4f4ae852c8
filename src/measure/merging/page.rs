//! The `merge-eval --html` page: every pair's verdict, score, overlap, error against the truth and
//! runner-up in one sortable table, failures and wrong accepts first, and each pair's two maps overlaid.

use image::RgbImage;

use crate::map::OccupancyMap;
use crate::measure::merging::PairRecord;
use crate::merge::compose::{overlay, OVERLAY_COLOURS};
use crate::merge::transform::Rigid;
use crate::support::error::Result;
use crate::support::report::{Cell, Figure, Report, Table};

/// Side of the box a pair's overlay is fitted into, pixels.
pub const PAIR_PICTURE: u32 = 480;

/// What became of a pair, worst first: the order of the page.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Outcome {
    /// Accepted, and wrong: two different places merged, or the same place at the wrong pose.
    WrongAccept,
    /// Declined although the right answer was among the candidates.
    DeclinedFound,
    /// Declined, the right answer not among the candidates.
    Declined,
    /// Accepted and accurate.
    Merged,
    /// Two different places, declined.
    NegativeDeclined,
}

impl Outcome {
    /// The outcome of a pair.
    pub fn of(r: &PairRecord) -> Outcome {
        match (r.negative, r.accepted, r.accurate) {
            (true, true, _) | (false, true, false) => Outcome::WrongAccept,
            (true, false, _) => Outcome::NegativeDeclined,
            (false, true, true) => Outcome::Merged,
            (false, false, _) if r.accurate_candidates.iter().any(|&a| a) => Outcome::DeclinedFound,
            (false, false, _) => Outcome::Declined,
        }
    }

    /// Its words on the page.
    pub fn label(self) -> &'static str {
        match self {
            Outcome::WrongAccept => "WRONG accept",
            Outcome::DeclinedFound => "declined, right pose found",
            Outcome::Declined => "declined",
            Outcome::Merged => "merged",
            Outcome::NegativeDeclined => "different places, declined",
        }
    }

    /// The row's colour: `bad` for wrong accepts, `warn` for missed pairs, `good` otherwise.
    pub fn class(self) -> &'static str {
        match self {
            Outcome::WrongAccept => "bad",
            Outcome::DeclinedFound | Outcome::Declined => "warn",
            Outcome::Merged | Outcome::NegativeDeclined => "good",
        }
    }
}

/// The pairs' indices in page order: wrong accepts, then missed pairs, then the rest, each in run order.
pub fn page_order(rows: &[PairRecord]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..rows.len()).collect();
    order.sort_by_key(|&i| (Outcome::of(&rows[i]), i));
    order
}

/// The anchor of pair `i`'s picture on the page.
pub fn anchor(i: usize) -> String {
    format!("pair-{i}")
}

/// The table (`id="pairs"`), rows in [`page_order`], each pair that `drawn` says has a picture on the
/// page linked to it.
pub fn html_table(rows: &[PairRecord], drawn: &dyn Fn(usize) -> bool) -> Table {
    let mut t = Table::new(
        "pairs",
        "Every pair: B (moved) onto A (reference). Score: the acceptance rule's value minus its threshold. \
         Overlap: the smaller share of either map's walls that lands in the other's known area. Errors \
         against the truth (positives only). Runner-up: the best other candidate.",
        &[
            ("#", true),
            ("A (reference)", false),
            ("B (moved)", false),
            ("group", false),
            ("verdict", false),
            ("score", true),
            ("overlap %", true),
            ("rotation error °", true),
            ("RMS error px", true),
            ("right pose at candidate", true),
            ("runner-up score", true),
            ("runner-up right", false),
            ("why declined", false),
            ("ms", true),
        ],
    );
    for i in page_order(rows) {
        let r = &rows[i];
        let outcome = Outcome::of(r);
        let truth = |v: f64| Cell::opt((!r.negative).then_some(v), 2);
        let found = r.accurate_candidates.iter().position(|&a| a);
        let runner = r.alignment.candidates.get(1);
        let runner_right = match (runner, r.negative) {
            (None, _) => "-",
            (Some(_), true) => "n/a",
            (Some(_), false) if r.accurate_candidates.get(1) == Some(&true) => "yes",
            (Some(_), false) => "no",
        };
        let mut number = Cell::int(i as i128);
        if drawn(i) {
            number = number.link(format!("#{}", anchor(i)));
        }
        t.row_with(
            vec![
                number,
                Cell::text(&r.dst),
                Cell::text(&r.src),
                Cell::text(&r.building),
                Cell::keyed(outcome.label(), outcome as u8 as f64),
                Cell::opt(Some(r.alignment.score), 3),
                Cell::num(100.0 * r.alignment.features.inside, 1),
                truth(r.rot_err_deg),
                truth(r.rms_px),
                Cell::opt(found.map(|k| k as f64 + 1.0), 0),
                Cell::opt(runner.map(|c| c.score), 3),
                Cell::text(runner_right),
                Cell::text(r.alignment.reason.as_deref().unwrap_or("")),
                Cell::num(r.ms, 1),
            ],
            Some(outcome.class()),
        );
    }
    t
}

/// How a pixel of the merge overlay ranks when a picture is shrunk: conflicts, then walls, then free
/// space, unknown last.
pub fn overlay_rank(p: image::Rgb<u8>) -> u8 {
    const RANK: [u8; 6] = [4, 3, 5, 2, 1, 6];
    OVERLAY_COLOURS
        .iter()
        .zip(RANK)
        .find(|((_, c), _)| *c == p.0)
        .map_or(0, |(_, r)| r)
}

/// The two maps overlaid at `t` (B's pixels to A's) in the [`OVERLAY_COLOURS`], cut to what either map
/// knows and fitted into [`PAIR_PICTURE`] pixels a side (enlarged by nearest neighbour, or shrunk keeping
/// walls and conflicts).
pub fn pair_picture(a: &OccupancyMap, b: &OccupancyMap, t: &Rigid) -> Result<RgbImage> {
    // The full-size overlay dropped as soon as it is cut.
    let full = crate::support::plot::crop_to_content(
        &overlay(a, b, t)?,
        crate::merge::compose::OVERLAY_UNKNOWN,
        4,
    );
    Ok(crate::support::plot::fit_image(
        &full,
        PAIR_PICTURE,
        PAIR_PICTURE,
        overlay_rank,
    ))
}

/// The caption lines under a pair's picture.
pub fn caption(i: usize, r: &PairRecord) -> Vec<String> {
    let outcome = Outcome::of(r);
    let mut lines = vec![
        format!("#{i} {}: {}", outcome.label(), r.building),
        format!("A {}  ·  B {}", r.dst, r.src),
        format!(
            "score {:+.3}, overlap {:.0}%, at {:.1}° ({:.1}, {:.1}) px",
            r.alignment.score,
            100.0 * r.alignment.features.inside,
            r.alignment.transform.theta_deg,
            r.alignment.transform.tx,
            r.alignment.transform.ty
        ),
    ];
    if !r.negative {
        lines.push(format!(
            "against the truth: {:.2}° and {:.2} px RMS",
            r.rot_err_deg, r.rms_px
        ));
    }
    if let Some(c) = r.alignment.candidates.get(1) {
        lines.push(format!(
            "runner-up: score {:+.3} at {:.1}° ({:.1}, {:.1}) px",
            c.score, c.transform.theta_deg, c.transform.tx, c.transform.ty
        ));
    }
    if let Some(why) = &r.alignment.reason {
        lines.push(format!("declined: {why}"));
    }
    lines
}

/// The legend of the pair pictures.
pub fn legend() -> Vec<(&'static str, image::Rgb<u8>)> {
    OVERLAY_COLOURS
        .iter()
        .map(|&(l, c)| (l, image::Rgb(c)))
        .collect()
}

/// The `merge-eval --html` page being written: each pair's pictures written as the pair is run (one
/// overlay in memory at a time), the page at the end.
pub struct PairsPage {
    report: Report,
    figures: Vec<(usize, Vec<Figure>)>,
    /// Pairs whose picture could not be drawn (a canvas over the overlay's size limit), and why.
    missing: Vec<(usize, String)>,
}

impl PairsPage {
    /// A page written into `dir`.
    pub fn create(dir: &std::path::Path) -> Result<Self> {
        Ok(PairsPage {
            report: Report::create(dir, "ogm-corners merge-eval")?,
            figures: Vec::new(),
            missing: Vec::new(),
        })
    }

    /// Draws pair `i` (A the reference map, B the moved one): the overlay at the estimate, and, when the
    /// estimate is not the truth, the overlay at the truth beside it. A pair whose overlay cannot be drawn
    /// (its canvas over [`overlay`]'s size limit: a far-off estimate) is listed without a picture; the run
    /// goes on. Only a failure to write a picture is an error.
    pub fn add(
        &mut self,
        i: usize,
        r: &PairRecord,
        a: &OccupancyMap,
        b: &OccupancyMap,
        truth: Option<Rigid>,
    ) -> Result<()> {
        let outcome = Outcome::of(r);
        let picture = match pair_picture(a, b, &r.alignment.transform) {
            Ok(p) => p,
            Err(e) => {
                self.missing.push((i, e.to_string()));
                return Ok(());
            }
        };
        let name = crate::support::report::file_name(i, "pair", "");
        let mut figure = self.report.picture(&name, &picture, caption(i, r))?;
        figure.id = Some(anchor(i));
        figure.class = Some(outcome.class()).filter(|c| *c != "warn");
        let mut figures = vec![figure];
        // The truth's overlay is drawn when it can be (see above).
        if let Some(picture) = truth
            .filter(|_| !r.accurate)
            .and_then(|t| pair_picture(a, b, &t).ok().map(|p| (t, p)))
        {
            let (t, picture) = picture;
            let name = crate::support::report::file_name(i, "pair", "-truth");
            let lines = vec![
                format!("#{i} at the true pose"),
                format!("{:.1}° ({:.1}, {:.1}) px", t.theta_deg, t.tx, t.ty),
            ];
            figures.push(self.report.picture(&name, &picture, lines)?);
        }
        self.figures.push((i, figures));
        Ok(())
    }

    /// Writes the page for `rows` (the run's records, in run order; `prep_ms` the mean preparation time)
    /// and returns its path.
    pub fn finish(mut self, rows: &[PairRecord], prep_ms: f64) -> Result<std::path::PathBuf> {
        let count = |o: Outcome| rows.iter().filter(|r| Outcome::of(r) == o).count();
        let positives = rows.iter().filter(|r| !r.negative).count();
        self.report.text(format!(
            "{} pairs ({} of one place, {} of different places): {} merged, {} wrong accepts, {} declined \
             with a right pose among the candidates, {} declined otherwise, {} different places declined. \
             Maps prepared in {:.0} ms on average. Click a column to sort; a pair's number leads to its \
             picture (a pair whose picture could not be drawn has none: {}).",
            rows.len(),
            positives,
            rows.len() - positives,
            count(Outcome::Merged),
            count(Outcome::WrongAccept),
            count(Outcome::DeclinedFound),
            count(Outcome::Declined),
            count(Outcome::NegativeDeclined),
            prep_ms,
            self.missing.len()
        ));
        let drawn: std::collections::HashSet<usize> =
            self.figures.iter().map(|(i, _)| *i).collect();
        self.report.table(html_table(rows, &|i| drawn.contains(&i)));
        if !self.missing.is_empty() {
            let mut t = Table::new(
                "undrawn",
                "Pairs without a picture, and why",
                &[("#", true), ("why", false)],
            );
            for (i, why) in &self.missing {
                t.row(vec![Cell::int(*i as i128), Cell::text(why)]);
            }
            self.report.table(t);
        }
        self.report.heading(
            "The pairs, wrong accepts and missed pairs first: A and B overlaid at the estimate",
        );
        self.report.legend(&legend());
        let rank: std::collections::HashMap<usize, usize> = page_order(rows)
            .into_iter()
            .enumerate()
            .map(|(k, i)| (i, k))
            .collect();
        self.figures.sort_by_key(|(i, _)| rank.get(i).copied());
        let figures = std::mem::take(&mut self.figures)
            .into_iter()
            .flat_map(|(_, f)| f)
            .collect();
        self.report.figures(figures);
        self.report.finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::merge::pair::align::declined;

    fn record(negative: bool, accepted: bool, accurate: bool, found: &[bool]) -> PairRecord {
        PairRecord {
            src: "b".into(),
            dst: "a".into(),
            building: "x".into(),
            negative,
            accepted,
            accurate,
            rot_err_deg: 0.0,
            rms_px: 0.0,
            alignment: declined("test"),
            ms: 1.0,
            accurate_candidates: found.to_vec(),
        }
    }

    #[test]
    fn wrong_accepts_and_missed_pairs_come_first() {
        let rows = [
            record(false, true, true, &[true]),          // merged
            record(true, false, false, &[]),             // negative declined
            record(false, false, false, &[false]),       // declined
            record(true, true, false, &[]),              // negative accepted: wrong
            record(false, false, false, &[false, true]), // declined, the right pose a candidate
            record(false, true, false, &[false]),        // accepted at the wrong pose
        ];
        let outcomes: Vec<Outcome> = rows.iter().map(Outcome::of).collect();
        assert_eq!(
            outcomes,
            [
                Outcome::Merged,
                Outcome::NegativeDeclined,
                Outcome::Declined,
                Outcome::WrongAccept,
                Outcome::DeclinedFound,
                Outcome::WrongAccept
            ]
        );
        assert_eq!(page_order(&rows), [3, 5, 4, 2, 0, 1]);
        let t = html_table(&rows, &|_| true);
        assert_eq!(t.len(), rows.len());
    }

    #[test]
    fn a_shrunk_overlay_keeps_conflicts_then_walls_then_free_space() {
        let rank = |i: usize| overlay_rank(image::Rgb(OVERLAY_COLOURS[i].1));
        // Conflict > walls of both > A only > B only > free in both > free in one > unknown.
        let order = [5, 2, 0, 1, 3, 4];
        assert!(order.windows(2).all(|w| rank(w[0]) > rank(w[1])));
        assert!(rank(4) > overlay_rank(crate::merge::compose::OVERLAY_UNKNOWN));
    }

    #[test]
    fn a_pair_that_cannot_be_drawn_is_listed_without_a_picture() {
        use crate::map::states::FREE;
        use crate::map::MapImage;
        // Two long corridors crossed at 90 degrees: the canvas would be far over the overlay's limit.
        let corridor = OccupancyMap::from_image(MapImage::filled(4000, 4, FREE).unwrap());
        let turned = Rigid {
            theta_deg: 90.0,
            tx: 2000.0,
            ty: -2000.0,
        };
        assert!(pair_picture(&corridor, &corridor, &turned).is_err());
        let dir = tempfile::tempdir().unwrap();
        let mut page = PairsPage::create(dir.path()).unwrap();
        let mut r = record(false, false, false, &[false]);
        r.alignment.transform = turned;
        page.add(0, &r, &corridor, &corridor, Some(Rigid::IDENTITY))
            .unwrap();
        let index = page.finish(&[r], 1.0).unwrap();
        let html = std::fs::read_to_string(index).unwrap();
        assert!(!html.contains("href=\"#pair-0\""), "a link to no picture");
        assert!(html.contains("id=\"undrawn\" data-rows=\"1\""));
        assert!(!html.contains("<img"));
    }

    #[test]
    fn a_pair_picture_fills_its_box_and_shows_conflicts() {
        use crate::map::states::{FREE, OCCUPIED, UNKNOWN};
        use crate::map::MapImage;
        // A room, and the same room with a wall across its middle where A is free.
        let room = |cross: bool| {
            let (w, h) = (120u32, 60u32);
            let mut img = MapImage::filled(w + 40, h + 40, UNKNOWN).unwrap();
            let stride = (w + 40) as usize;
            for y in 20..20 + h {
                for x in 20..20 + w {
                    let wall =
                        x == 20 || y == 20 || x == 19 + w || y == 19 + h || (cross && x == 80);
                    img.pixels_mut()[y as usize * stride + x as usize] =
                        if wall { OCCUPIED } else { FREE };
                }
            }
            OccupancyMap::from_image(img)
        };
        let pic = pair_picture(&room(false), &room(true), &Rigid::IDENTITY).unwrap();
        // The known part (128x68 with the margin) fitted: the width spans the box exactly.
        assert_eq!(pic.width(), PAIR_PICTURE);
        let h = (f64::from(PAIR_PICTURE) * 68.0 / 128.0).round() as u32;
        assert!(pic.height().abs_diff(h) <= 1, "{} vs {h}", pic.height());
        let has = |c: [u8; 3]| pic.pixels().any(|p| p.0 == c);
        assert!(has(OVERLAY_COLOURS[5].1), "the crossing wall is a conflict");
        assert!(has(OVERLAY_COLOURS[2].1), "the room's walls agree");
    }
}
