//! `merge-eval`: the merger over a pair set with ground truth, per pair and summed per building.

use std::collections::HashMap;
use std::io::{self, Write};
use std::path::Path;
use std::time::Instant;

use serde::Serialize;

use super::align::{align_prepared, Alignment, MergeOptions, Prepared};
use super::pairs::PairSet;
use crate::error::Result;
use crate::map::OccupancyMap;

/// One pair's outcome.
#[derive(Clone, Debug, Serialize)]
pub struct PairRecord {
    /// The moved map.
    pub src: String,
    /// The reference map.
    pub dst: String,
    /// Its building ("negative" for pairs of different places).
    pub building: String,
    /// A pair of different places.
    pub negative: bool,
    /// The merger accepted it.
    pub accepted: bool,
    /// The estimate passes the success test (false for negatives).
    pub accurate: bool,
    /// Rotation error, degrees (negatives: 0).
    pub rot_err_deg: f64,
    /// RMS error over the annotated points, pixels (negatives: 0).
    pub rms_px: f64,
    /// The alignment.
    pub alignment: Alignment,
    /// Time of `align` on the prepared maps, milliseconds.
    pub ms: f64,
}

/// Runs the merger on every pair and negative of `set`, maps read from `maps/<NAME>.png` (or `.pgm`,
/// `.yaml`), each map prepared once.
pub fn run(set: &PairSet, maps: &Path, options: &MergeOptions) -> Result<(Vec<PairRecord>, f64)> {
    let mut prepared: HashMap<String, Prepared> = HashMap::new();
    let mut prep_ms = 0.0;
    let mut get = |name: &str, prepared: &mut HashMap<String, Prepared>| -> Result<()> {
        if !prepared.contains_key(name) {
            let path = ["yaml", "png", "pgm"]
                .iter()
                .map(|e| maps.join(format!("{name}.{e}")))
                .find(|p| p.is_file())
                .unwrap_or_else(|| maps.join(format!("{name}.png")));
            let map = OccupancyMap::load(&path)?;
            let t = Instant::now();
            prepared.insert(name.to_string(), Prepared::new(&map));
            prep_ms += t.elapsed().as_secs_f64() * 1e3;
        }
        Ok(())
    };
    let mut out = Vec::new();
    let jobs = set
        .pairs
        .iter()
        .map(|p| (p.src.clone(), p.dst.clone(), Some(p)))
        .chain(
            set.negatives
                .iter()
                .map(|n| (n.src.clone(), n.dst.clone(), None)),
        );
    for (src, dst, truth) in jobs {
        get(&src, &mut prepared)?;
        get(&dst, &mut prepared)?;
        let t = Instant::now();
        let alignment = align_prepared(&prepared[&dst], &prepared[&src], options)?;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        let (accurate, rot, rms) = match truth {
            Some(p) => {
                let (rot, rms) = p.errors(&alignment.transform);
                (p.accurate(&alignment.transform), rot, rms)
            }
            None => (false, 0.0, 0.0),
        };
        out.push(PairRecord {
            building: truth.map_or("negative".to_string(), |p| p.building.clone()),
            negative: truth.is_none(),
            accepted: alignment.accepted,
            accurate,
            rot_err_deg: rot,
            rms_px: rms,
            src,
            dst,
            alignment,
            ms,
        });
    }
    let n = prepared.len().max(1) as f64;
    Ok((out, prep_ms / n))
}

/// The row of the pairs the acceptance rule was fitted on.
pub const CALIBRATION: &str = "calibration half (src number even)";
/// The row of the others.
pub const HELD_OUT: &str = "held-out half (src number odd)";

/// Whether a pair belongs to the calibration half: its src map's trailing number is even.
pub fn calibration(src: &str) -> bool {
    let digits: String = src
        .chars()
        .rev()
        .take_while(char::is_ascii_digit)
        .collect::<String>()
        .chars()
        .rev()
        .collect();
    digits.parse::<u64>().is_ok_and(|n| n % 2 == 0)
}

/// Per building (and "all", and the negatives): pairs, accepted and accurate, accurate if all were
/// accepted, wrong accepts, median and p90 ms.
pub fn write_summary(out: &mut dyn Write, rows: &[PairRecord], prep_ms: f64) -> io::Result<()> {
    let mut groups: Vec<String> = Vec::new();
    for r in rows {
        if !groups.contains(&r.building) {
            groups.push(r.building.clone());
        }
    }
    groups.push(CALIBRATION.to_string());
    groups.push(HELD_OUT.to_string());
    groups.push("all".to_string());
    writeln!(
        out,
        "| building | pairs | accepted and accurate | accurate if all accepted | wrong accepts | median ms | p90 ms |"
    )?;
    writeln!(out, "|---|---|---|---|---|---|---|")?;
    for g in &groups {
        let sel: Vec<&PairRecord> = rows
            .iter()
            .filter(|r| match g.as_str() {
                "all" => !r.negative,
                CALIBRATION => !r.negative && calibration(&r.src),
                HELD_OUT => !r.negative && !calibration(&r.src),
                _ => &r.building == g,
            })
            .collect();
        let n = sel.len();
        let ok = sel.iter().filter(|r| r.accepted && r.accurate).count();
        let could = sel.iter().filter(|r| r.accurate).count();
        let wrong = sel.iter().filter(|r| r.accepted && !r.accurate).count();
        let mut ms: Vec<f64> = sel.iter().map(|r| r.ms).collect();
        ms.sort_by(f64::total_cmp);
        let q = |f: f64| {
            ms.get(((ms.len() as f64 - 1.0) * f).round() as usize)
                .copied()
                .unwrap_or(0.0)
        };
        let pct = |k: usize| 100.0 * k as f64 / n.max(1) as f64;
        writeln!(
            out,
            "| {g} | {n} | {ok} ({:.1}%) | {could} ({:.1}%) | {wrong} | {:.0} | {:.0} |",
            pct(ok),
            pct(could),
            q(0.5),
            q(0.9)
        )?;
    }
    writeln!(
        out,
        "\nPreparing a map (once per map): {prep_ms:.0} ms on average."
    )?;
    writeln!(
        out,
        "\nOperating curve: the acceptance rule's threshold moved by an offset (0 is the default; the \
         coarse ratio must stay at least {}):\n",
        super::align::MIN_COARSE_RATIO
    )?;
    writeln!(
        out,
        "| threshold offset | accepted | accepted and accurate | wrong accepts | negatives accepted |"
    )?;
    writeln!(out, "|---|---|---|---|---|")?;
    for (offset, accepted, correct, wrong, negatives) in operating_curve(rows) {
        writeln!(
            out,
            "| {offset:+.2} | {accepted} | {correct} | {wrong} | {negatives} |"
        )?;
    }
    Ok(())
}

/// Offsets of the operating curve.
pub const CURVE_OFFSETS: [f64; 11] = [-1.0, -0.5, -0.3, -0.2, -0.1, 0.0, 0.1, 0.2, 0.3, 0.5, 1.0];

/// For each offset of [`CURVE_OFFSETS`] added to the rule's threshold: accepted pairs of one place,
/// accepted and accurate ones, wrong accepts among them, and accepted negatives.
pub fn operating_curve(rows: &[PairRecord]) -> Vec<(f64, usize, usize, usize, usize)> {
    CURVE_OFFSETS
        .iter()
        .map(|&o| {
            let acc = |r: &&PairRecord| {
                r.alignment.score >= o
                    && r.alignment.features.coarse_ratio >= super::align::MIN_COARSE_RATIO
            };
            let pos: Vec<&PairRecord> = rows.iter().filter(|r| !r.negative).filter(acc).collect();
            let negatives = rows.iter().filter(|r| r.negative).filter(acc).count();
            let correct = pos.iter().filter(|r| r.accurate).count();
            (o, pos.len(), correct, pos.len() - correct, negatives)
        })
        .collect()
}
