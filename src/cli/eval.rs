//! `ogm-corners eval`: repeatability of every detector under known transforms (see [`ogm_corners::measure::detection`]).

use std::path::PathBuf;

use clap::Args;

use ogm_corners::backend::reference_working_bytes;
use ogm_corners::map::output_names;
use ogm_corners::measure::detection::page::{self, EvalPage};
use ogm_corners::measure::detection::{self, MAX_TRIALS};
use ogm_corners::support::files;
use ogm_corners::support::memory::Budget;
use ogm_corners::{DetectOptions, Error, OccupancyMap, Result};

use super::{detector_on, write_stdout, BackendArg, TableFormat, ALL_DETECTORS};

/// A map's file stem: its name in an annotation file.
fn stem(p: &std::path::Path) -> &str {
    p.file_stem().and_then(|s| s.to_str()).unwrap_or("")
}

#[derive(Args, Debug)]
pub(super) struct EvalArgs {
    /// Maps (yaml or image), or folders of them (searched as `detect` searches them).
    #[arg(required = true)]
    maps: Vec<PathBuf>,
    /// Random trials per condition (exact transforms run once), at most 1000.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=i64::from(MAX_TRIALS)))]
    trials: u32,
    /// Seed of the random transforms.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Match distance, pixels.
    #[arg(long, default_value_t = 2.0)]
    tolerance: f64,
    /// Output format.
    #[arg(long, value_enum, default_value = "md")]
    format: TableFormat,
    /// Where to run the detectors.
    #[arg(long, value_enum, default_value = "auto")]
    backend: BackendArg,
    /// Also write plots of repeatability against noise and rotation (averaged over the maps) to DIR; with
    /// --annotations, a picture per annotated map instead (`NAME-marked.png`: the marked points, the
    /// paper's keypoints and the robust detector's strongest three per marked point).
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,
    /// Instead of repeatability: recall of the hand-marked points in FILE (`{"maps": {NAME: [[x, y],
    /// ...]}}`, NAME a map's file stem, pixel centres at integers) within 5 and 10 px, keypoints per map,
    /// and recall at a budget of 1x and 3x the marked points (strongest first), per map and pooled.
    #[arg(long, value_name = "FILE")]
    annotations: Option<PathBuf>,
    /// Also write an HTML report into DIR: `index.html` with the table (sortable by a click on a column),
    /// the plots, and each map's keypoints per detector (with --annotations: the marked points against the
    /// paper's and the robust detector's keypoints); opened from disk, no server.
    #[arg(long, value_name = "DIR")]
    html: Option<PathBuf>,
    #[command(flatten)]
    robust: super::RobustArgs,
}

pub(super) fn run(a: EvalArgs, budget: &Budget) -> Result<()> {
    if !(a.tolerance.is_finite() && a.tolerance >= 0.0) {
        return Err(Error::invalid(format!(
            "--tolerance must be a number >= 0, got {}",
            a.tolerance
        )));
    }
    super::check_stdout()?;
    // Every path is checked before the first (long) evaluation; the plots must not overwrite a map.
    // The transformed pairs, and the largest buffers any backend takes for any detector (the reference's).
    let extra = |w: u32, h: u32| {
        let worst = ALL_DETECTORS
            .iter()
            .map(|&d| {
                let o = DetectOptions {
                    detector: d,
                    ..DetectOptions::default()
                };
                reference_working_bytes(&o, w, h)
            })
            .max()
            .unwrap_or(0);
        let sheet = if a.html.is_some() {
            ogm_corners::measure::compare::SHEET_BYTES
        } else {
            0
        };
        detection::evaluate_bytes(w, h)
            .saturating_add(worst)
            .saturating_add(sheet)
    };
    let (maps, mut inputs) = super::map_inputs(&a.maps, budget, &extra)?;
    // Maps are named by their first distinctive path component, made unique.
    let names = output_names(&maps);
    // The annotated maps are named by their file stems, as the annotation file names them.
    let stems: Vec<String> = maps.iter().map(|p| stem(p).to_string()).collect();
    if let Some(dir) = &a.html {
        inputs.claim_output(&dir.join(ogm_corners::support::report::INDEX), "--html")?;
        let marked = a.annotations.is_some();
        let named = if marked { &stems } else { &names };
        for file in page::picture_files(named, marked) {
            inputs.claim_output(&dir.join(file), "--html")?;
        }
    }
    if let Some(dir) = &a.plot {
        if a.annotations.is_some() {
            for name in &stems {
                let file = detection::annotations::marked_sheet_file(name);
                inputs.claim_output(&dir.join(file), "--plot")?;
            }
        } else {
            for file in detection::PLOT_FILES {
                inputs.claim_output(&dir.join(file), "--plot")?;
            }
        }
    }
    // Every detector with its default (the paper's) options; the robust one with those given.
    let base = DetectOptions {
        robust: a.robust.params(),
        ..DetectOptions::default()
    };
    let mut detector = detector_on(a.backend, base)?;
    let mut page = a.html.as_deref().map(EvalPage::create).transpose()?;
    if let Some(file) = &a.annotations {
        return annotated(&a, file, &maps, &mut detector, &base, budget, page);
    }
    let mut rows = Vec::new();
    // One map in memory at a time.
    for (i, (p, name)) in maps.iter().zip(&names).enumerate() {
        let map = OccupancyMap::load_within(p, budget, &extra)?;
        rows.extend(detection::evaluate(
            &mut detector,
            name,
            &map.image,
            &ALL_DETECTORS,
            &base,
            a.trials,
            a.seed,
            a.tolerance,
        )?);
        if let Some(page) = &mut page {
            // What each detector finds on the map as it is, for a person to judge the numbers by.
            let mut found = Vec::new();
            for &kind in &ALL_DETECTORS {
                detector.set_options(DetectOptions {
                    detector: kind,
                    ..base
                });
                found.push((kind, detector.detect(&map)?.keypoints));
            }
            let sheet = ogm_corners::measure::compare::contact_sheet(name, &map, &found);
            page.add_map(i, name, p, &sheet, false)?;
        }
    }
    if let Some(page) = page {
        let about = format!(
            "{} maps; {} trials per random condition (seed {}), match tolerance {} px.",
            maps.len(),
            a.trials,
            a.seed,
            a.tolerance
        );
        let index = page.finish_repeatability(&rows, &about)?;
        ogm_corners::say!(
            "ogm-corners: wrote {}",
            ogm_corners::support::error::one_line(&index.display().to_string())
        );
    }
    if let Some(dir) = &a.plot {
        files::create_dir(dir)?;
        for (file, picture) in detection::repeatability_plots(&rows) {
            let path = dir.join(file);
            files::write_png(&path, &picture)?;
            ogm_corners::say!(
                "ogm-corners: wrote {}",
                ogm_corners::support::error::one_line(&path.display().to_string())
            );
        }
    }
    write_stdout(|out| detection::write_table(out, a.format.into(), &rows))
}

/// `eval --annotations`: recall of the marked points on every annotated map, per detector.
fn annotated(
    a: &EvalArgs,
    file: &std::path::Path,
    maps: &[PathBuf],
    detector: &mut ogm_corners::Detector,
    base: &DetectOptions,
    budget: &Budget,
    mut page: Option<EvalPage>,
) -> Result<()> {
    use ogm_corners::measure::detection::annotations::{pooled, recall, write_table, Annotations};
    let marks = Annotations::load(file)?;
    let mut rows = Vec::new();
    for (i, p) in maps.iter().enumerate() {
        let name = stem(p);
        let Some(points) = marks.points(name) else {
            ogm_corners::say!(
                "ogm-corners: note: {}: no marked points for `{name}` in {}",
                p.display(),
                file.display()
            );
            continue;
        };
        let map = OccupancyMap::load_within(p, budget, &|w, h| {
            ALL_DETECTORS
                .iter()
                .map(|&d| {
                    let options = DetectOptions {
                        detector: d,
                        ..DetectOptions::default()
                    };
                    detector.working_bytes_with(&options, w, h)
                })
                .max()
                .unwrap_or(0)
                .saturating_add(if a.plot.is_some() || page.is_some() {
                    ogm_corners::measure::detection::annotations::MARKED_SHEET_BYTES
                } else {
                    0
                })
        })?;
        marks
            .check_within(name, map.image.width(), map.image.height())
            .map_err(|m| Error::input(file, m))?;
        // The paper's detector both ways of reading unknown neighbours, then the baselines.
        let unknown_blocks = DetectOptions {
            unknown_as_occupied: true,
            ..*base
        };
        let runs = std::iter::once((*base, "ogm"))
            .chain([(unknown_blocks, "ogm-unknown-as-occupied")])
            .chain(ALL_DETECTORS[1..].iter().map(|&d| {
                let o = DetectOptions {
                    detector: d,
                    ..*base
                };
                (o, d.name())
            }));
        let mut paper = Vec::new();
        let mut robust = Vec::new();
        for (options, label) in runs {
            detector.set_options(options);
            let found = detector.detect(&map)?;
            rows.push(recall(name, label, points, &found.keypoints));
            match label {
                "ogm" => paper = found.keypoints,
                "ogm-robust" => robust = found.keypoints,
                _ => {}
            }
        }
        if a.plot.is_none() && page.is_none() {
            continue;
        }
        let sheet = ogm_corners::measure::detection::annotations::marked_sheet(
            name, &map, points, &paper, &robust,
        );
        if let Some(dir) = &a.plot {
            files::create_dir(dir)?;
            let path =
                dir.join(ogm_corners::measure::detection::annotations::marked_sheet_file(name));
            files::write_png(&path, &sheet)?;
            ogm_corners::say!(
                "ogm-corners: wrote {}",
                ogm_corners::support::error::one_line(&path.display().to_string())
            );
        }
        if let Some(page) = &mut page {
            page.add_map(i, name, p, &sheet, true)?;
        }
    }
    if rows.is_empty() {
        return Err(Error::input(
            file,
            format!(
                "none of the maps has marked points here (annotated: {})",
                marks.names().join(", ")
            ),
        ));
    }
    let total = pooled(&rows);
    rows.extend(total);
    if let Some(page) = page {
        let index = page.finish_recall(&rows, file)?;
        ogm_corners::say!(
            "ogm-corners: wrote {}",
            ogm_corners::support::error::one_line(&index.display().to_string())
        );
    }
    write_stdout(|out| write_table(out, a.format.into(), &rows))
}
