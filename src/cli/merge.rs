//! `ogm-corners merge A B`: align map B onto map A with no initial pose, and write the merged map when the
//! alignment is confident (see [`ogm_corners::merge`]). With more maps, a folder, or `--poses` /
//! `--init-poses`: every map placed at once (`merge_many.rs`).
//!
//! Two maps: both images are read within the budget; `merge::footprint::pair` counts B brought to A's
//! cells and both maps' preparations before anything is allocated; then `merge::pair::merge_pair` aligns
//! them (its stages: `ogm_corners::merge::pair`). The verdict (`merge::pair::Verdict`) is printed; when
//! accepted, the canvas is counted (`merge::footprint::canvas`), and the merged map
//! (`merge::pair::compose_pair`, via `merge::compose`) and the picture (`merge::pair::overlay_pair`) are
//! staged and renamed into place together (`support::files::Staged`). A declined merge writes nothing
//! and exits 3.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use serde::Serialize;

use ogm_corners::map::{merged_yaml_text, save_names, write_merged_pgm_to};
use ogm_corners::merge::footprint::{self, check_alignable};
use ogm_corners::merge::pair::{self, Verdict};
use ogm_corners::merge::{compose, MergeOptions};
use ogm_corners::support::files;
use ogm_corners::support::memory::Budget;
use ogm_corners::{Error, OccupancyMap, Result};

use super::write_stdout;

#[derive(Args, Debug)]
pub(super) struct MergeArgs {
    /// The maps (yaml or image) or folders of maps. Two maps: B aligned onto A (the merged map is in A's
    /// frame). More, or a folder: every map placed at once, each group's merged map in the frame of its
    /// first map.
    #[arg(required_unless_present = "from", value_name = "A B | MAPS... | DIR")]
    pub(super) maps: Vec<PathBuf>,
    /// Add the maps given to an earlier many-map merge: read the maps its `--poses` FILE lists (by the
    /// paths recorded there) and the pairs it aligned, and align only the pairs with a new or changed
    /// map (the old pairs count as aligned); then place every map afresh. FILE may also be the new
    /// `--poses` (it is replaced only once everything is written).
    #[arg(long, value_name = "FILE")]
    pub(super) from: Option<PathBuf>,
    /// Write the merged map: `NAME.yaml` (with `NAME.pgm` beside it) or `NAME.pgm`. Only when merged; with
    /// many maps, group 0 as NAME and group k as `NAME-k`.
    #[arg(short, long, value_name = "MERGED.yaml|.pgm")]
    pub(super) output: Option<PathBuf>,
    /// Write a picture of the alignment (two maps: A and B in two colours, agreement and conflicts; many:
    /// every map's walls in its own colour), with a legend of the colours below it. Only when merged; with
    /// many maps, per group as for `-o`.
    #[arg(long, value_name = "PNG")]
    pub(super) overlay: Option<PathBuf>,
    /// Place every map at once (also for two) and write each map's pose in its group's merged map as JSON.
    #[arg(long, value_name = "FILE")]
    pub(super) poses: Option<PathBuf>,
    /// Place every map at once and write the multirobot_map_merge parameters (`init_pose_x/y/z/yaw` per
    /// robot, for `known_init_poses: true`) as a rosparam yaml.
    #[arg(long, value_name = "YAML")]
    pub(super) init_poses: Option<PathBuf>,
    /// Place every map at once (also for two) and write an HTML report into DIR: `index.html` with every
    /// map's pose (maps left out first), every pair's verdict, each group's picture with its maps'
    /// colours, and each map alone (sortable tables; opened from disk, no server).
    #[arg(long, value_name = "DIR")]
    pub(super) html: Option<PathBuf>,
    /// Many maps: in a set of more than 12, align each map first with only its N most similar maps (by
    /// their corners' layout), then the pairs that close cycles and may join groups, instead of every
    /// pair (0: every pair).
    #[arg(long, value_name = "N", default_value_t = 3, value_parser = clap::value_parser!(u32).range(0..=1000))]
    pub partners: u32,
    /// Output format of the verdict.
    #[arg(long, value_enum, default_value = "text")]
    pub(super) format: super::TextOrJson,
    /// Where the candidates are scored (the transform-scoring kernel): the same counts, so the same
    /// verdict, on every backend. The CPU by default: a pair scores a handful of candidates, less work
    /// than opening a GPU. With many maps, the placement's dense checks (the pairs are aligned on every
    /// CPU core).
    #[arg(long, value_enum, default_value = "cpu")]
    pub(super) backend: super::BackendArg,
}

/// The JSON verdict, with the time it took.
#[derive(Serialize)]
struct Timed {
    #[serde(flatten)]
    verdict: Verdict,
    seconds: f64,
}

impl MergeArgs {
    /// Whether this is the two-map merge (two map files and no output only many-map mode writes);
    /// otherwise every map is placed at once (`merge_many`).
    pub(super) fn is_pair(&self) -> bool {
        self.maps.len() == 2
            && self.maps.iter().all(|p| !p.is_dir())
            && self.poses.is_none()
            && self.init_poses.is_none()
            && self.html.is_none()
            && self.from.is_none()
    }
}

/// The two-map merge ([`MergeArgs::is_pair`]).
pub(super) fn run(a: MergeArgs, budget: &Budget) -> Result<()> {
    super::check_stdout()?;
    let mut inputs = files::Inputs::new();
    // The images first; what merging them needs is counted once they are read (below).
    let mut raw = 0u64;
    for p in &a.maps {
        let (w, h) = super::claim_input(p, budget, &|_, _| 0, &mut inputs)?;
        raw = raw.saturating_add(u64::from(w) * u64::from(h));
        budget.check(format_args!("{} maps", a.maps.len()), raw)?;
    }
    let (yaml_out, pgm_out) = save_names(a.output.as_deref())?;
    for (p, what) in [
        (&yaml_out, "-o"),
        (&pgm_out, "-o"),
        (&a.overlay, "--overlay"),
    ] {
        if let Some(p) = p {
            inputs.claim_output(p, what)?;
            // A missing or read-only folder is found now, not after the work.
            files::check_writable(p)?;
        }
    }
    let map_a = OccupancyMap::load_within(&a.maps[0], budget, &|_, _| 0)?;
    let map_b = OccupancyMap::load_within(&a.maps[1], budget, &|w, h| {
        u64::from(map_a.image.width()) * u64::from(map_a.image.height())
            + u64::from(w) * u64::from(h)
    })?;
    for w in map_a.warnings.iter().chain(&map_b.warnings) {
        ogm_corners::say!(
            "ogm-corners: warning: {}",
            ogm_corners::support::error::one_line(w)
        );
    }
    // B at A's resolution and both preparations over their explored parts, before any is allocated.
    let (fa, fb) = footprint::pair(&map_a, &map_b)?;
    budget.check(
        format_args!(
            "merging {} ({}x{}, explored {}x{}) and {} ({}x{} at A's cells, explored {}x{})",
            a.maps[0].display(),
            fa.width,
            fa.height,
            fa.crop.0,
            fa.crop.1,
            a.maps[1].display(),
            fb.width,
            fb.height,
            fb.crop.0,
            fb.crop.1
        ),
        fa.bytes().saturating_add(fb.bytes()),
    )?;
    check_alignable(&fa, &fb)?;
    let mut backend = super::backend_on(a.backend)?;
    let start = Instant::now();
    let merged = pair::merge_pair(&map_a, &map_b, &MergeOptions::default(), backend.as_mut())?;
    let seconds = start.elapsed().as_secs_f64();
    print_verdict(a.format, &merged, seconds)?;
    let al = &merged.alignment;
    if !al.accepted {
        return Err(Error::Declined(
            al.reason
                .clone()
                .unwrap_or_else(|| "not confident".to_string()),
        ));
    }
    // The merged map and the picture are as large as the canvas: counted before they are made (the
    // transform moves B at A's cells).
    let canvas = footprint::canvas(&map_a, &fb, &al.transform)?;
    let per_px = u64::from(pgm_out.is_some()) + 6 * u64::from(a.overlay.is_some());
    budget.check(
        format_args!(
            "the merged map and picture ({}x{} pixels)",
            canvas.width(),
            canvas.height()
        ),
        (fa.bytes() + fb.bytes()).saturating_add(canvas.pixels().saturating_mul(per_px)),
    )?;
    // The merged map, its yaml and the picture renamed into place together: a failure leaves none.
    let mut staged = files::Staged::default();
    let mut wrote = Vec::new();
    if let Some(pgm) = &pgm_out {
        let merged_map = pair::compose_pair(&map_a, &map_b, &al.transform)?;
        staged.write(pgm, |out| write_merged_pgm_to(&merged_map, out))?;
        if let Some(yaml) = &yaml_out {
            let text = merged_yaml_text(pgm, &merged_map, "A");
            staged.write(yaml, |out| out.write_all(text.as_bytes()))?;
        }
        wrote.push(pgm);
    }
    if let Some(png) = &a.overlay {
        let picture = pair::overlay_pair(&map_a, &map_b, &al.transform)?;
        let picture = ogm_corners::support::plot::with_legend(&picture, &compose::overlay_legend());
        staged.write(png, |out| files::encode_png(out, &picture))?;
        wrote.push(png);
    }
    staged.commit()?;
    for p in wrote {
        ogm_corners::say!(
            "ogm-corners: wrote {}",
            ogm_corners::support::error::one_line(&p.display().to_string())
        );
    }
    Ok(())
}

/// The verdict on standard output: JSON (the verdict and the seconds) or one line with its why.
fn print_verdict(format: super::TextOrJson, merged: &pair::PairMerge, seconds: f64) -> Result<()> {
    let (al, world) = (&merged.alignment, merged.world);
    write_stdout(|out| match format {
        super::TextOrJson::Json => {
            serde_json::to_writer_pretty(
                &mut *out,
                &Timed {
                    verdict: merged.verdict(),
                    seconds,
                },
            )?;
            writeln!(out)
        }
        super::TextOrJson::Text => {
            let t = &al.transform;
            let verdict = if al.accepted {
                "merged".to_string()
            } else {
                format!(
                    "not merged: {}",
                    al.reason.as_deref().unwrap_or("not confident")
                )
            };
            write!(
                out,
                "{verdict}; score {:.2}, overlap {:.0}%; B -> A: {:.2} deg, ({:.1}, {:.1}) px",
                al.score,
                100.0 * al.features.inside,
                t.theta_deg,
                t.tx,
                t.ty
            )?;
            if let Some(w) = world {
                write!(out, " = {w}")?;
            }
            writeln!(out, "; {:.0} ms", seconds * 1e3)?;
            writeln!(out, "why: {}", al.explain())
        }
    })
}
