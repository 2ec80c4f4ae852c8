//! `merge-eval`: the merger over a pair set with ground truth, per pair and summed per building; the hard
//! synthetic families (`families.rs`); leave-one-building-out cross-validation (`crossval.rs`); what was
//! measured kept on disk (`cache.rs`); many maps at once, `merge-eval --global` (`many.rs`); and its
//! page (`page.rs`).

pub mod cache;
pub mod crossval;
pub mod families;
pub mod many;
pub mod page;

use std::collections::HashMap;
use std::io::{self, Write};
use std::path::Path;
use std::time::Instant;

use serde::Serialize;

use crate::backend::baselines::Baseline;
use crate::backend::DetectorKind;
use crate::map::OccupancyMap;
use crate::measure::pairs::{PairSet, TruePair};
use crate::measure::synthetic::{furnished_pair, synthetic_pair, SyntheticPair, SyntheticSpec};
use crate::merge::pair::align::{align_prepared, Alignment, MergeOptions, Prepared};
use crate::merge::pair::hypotheses::Hypotheses;
use crate::merge::transform::Rigid;
use crate::support::error::Result;

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
    /// Which of the alignment's candidates pass the success test (empty for negatives): whether the
    /// right answer was found but not chosen.
    pub accurate_candidates: Vec<bool>,
}

/// The file of map `name` in the folder `maps`: `NAME.yaml`, `.png` or `.pgm`, the first that exists;
/// an error naming all three when none does.
pub fn map_path(maps: &Path, name: &str) -> Result<std::path::PathBuf> {
    MAP_EXTENSIONS
        .iter()
        .map(|e| maps.join(format!("{name}.{e}")))
        // Anything there, not only a regular file: loading then says what it is (a fifo, a device).
        .find(|p| p.exists())
        .ok_or_else(|| {
            crate::support::error::Error::input(
                maps,
                format!(
                    "no map {name:?} in this folder (looked for {})",
                    MAP_EXTENSIONS.map(|e| format!("{name}.{e}")).join(", ")
                ),
            )
        })
}

/// The files a pair file's map name may stand for, in the order they are looked for.
const MAP_EXTENSIONS: [&str; 3] = ["yaml", "png", "pgm"];

/// Sees each pair as it is run: its index, its record, A (the reference map), B (the moved map), and the
/// true transform of B's pixels to A's when known. How `--html` draws the pairs without holding them.
pub type OnPair<'a> =
    dyn FnMut(usize, &PairRecord, &OccupancyMap, &OccupancyMap, Option<Rigid>) -> Result<()> + 'a;

/// Runs the merger on every pair and negative of `set`, maps read from `maps/<NAME>.png` (or `.pgm`,
/// `.yaml`), each map prepared once.
pub fn run(
    set: &PairSet,
    maps: &Path,
    options: &MergeOptions,
) -> Result<(Vec<PairRecord>, MapCosts)> {
    run_with(set, maps, options, &mut |_, _, _, _, _| Ok(()))
}

/// [`run`], showing each pair to `on_pair` as it is done.
pub fn run_with(
    set: &PairSet,
    maps: &Path,
    options: &MergeOptions,
    on_pair: &mut OnPair,
) -> Result<(Vec<PairRecord>, MapCosts)> {
    run_cached(set, maps, options, on_pair, None)
}

/// A map of a pair set while its pairs run: its content id when there is a cache (hashed once, not per
/// pair), and prepared only when some pair of it is not in the cache.
struct Held {
    map: OccupancyMap,
    id: Option<crate::merge::many::ContentId>,
    prepared: Option<Prepared>,
}

/// [`run_with`], each pair's alignment read from `cache` when it was measured before (the same maps'
/// contents, options and build) and kept there when not; a map is prepared only for a pair not found.
pub fn run_cached(
    set: &PairSet,
    maps: &Path,
    options: &MergeOptions,
    on_pair: &mut OnPair,
    mut cache: Option<&mut cache::RecordCache>,
) -> Result<(Vec<PairRecord>, MapCosts)> {
    let mut held: HashMap<String, Held> = HashMap::new();
    let mut timer = PrepTimer::default();
    let mut out = Vec::new();
    let jobs = jobs(set);
    let last = last_uses(&jobs);
    for (k, (src, dst, truth)) in jobs.into_iter().enumerate() {
        for name in [src, dst] {
            if !held.contains_key(name) {
                let map = OccupancyMap::load(map_path(maps, name)?)?;
                let id = cache
                    .is_some()
                    .then(|| crate::merge::many::content_id(&map));
                held.insert(
                    name.to_string(),
                    Held {
                        map,
                        id,
                        prepared: None,
                    },
                );
            }
        }
        let key = match (cache.as_deref(), held[dst].id, held[src].id) {
            (Some(c), Some(a), Some(b)) => Some(c.key(a, b, options)),
            _ => None,
        };
        let found = match (&mut cache, &key) {
            (Some(c), Some(key)) => c.get(key),
            _ => None,
        };
        let (alignment, ms) = match found {
            Some(kept) => kept,
            None => {
                for name in [src, dst] {
                    let h = held.get_mut(name).expect("loaded above");
                    if h.prepared.is_none() {
                        h.prepared =
                            Some(timer.prepare_with(&h.map, options.hypotheses.detector())?);
                    }
                }
                let prepared = |name: &str| held[name].prepared.as_ref().expect("prepared above");
                let (alignment, ms) = timer.align(prepared(dst), prepared(src), options);
                let alignment = alignment?;
                if let (Some(c), Some(key)) = (&mut cache, &key) {
                    c.put(key, &alignment, ms);
                }
                (alignment, ms)
            }
        };
        let record = pair_record(src, dst, truth, alignment, ms);
        on_pair(
            out.len(),
            &record,
            &held[dst].map,
            &held[src].map,
            truth.map(TruePair::truth),
        )?;
        out.push(record);
        // A map no later pair names is let go: a set of cut pairs names each map once.
        held.retain(|name, _| last[name.as_str()] > k);
    }
    Ok((out, timer.costs()))
}

/// The record of aligning `src` onto `dst` (`alignment`, in `ms`), judged against `truth` (none: a
/// negative).
fn pair_record(
    src: &str,
    dst: &str,
    truth: Option<&TruePair>,
    alignment: Alignment,
    ms: f64,
) -> PairRecord {
    let accurate_candidates = match truth {
        Some(p) => alignment
            .candidates
            .iter()
            .map(|c| p.accurate(&c.transform))
            .collect(),
        None => Vec::new(),
    };
    let (accurate, rot, rms) = match truth {
        Some(p) => {
            let (rot, rms) = p.errors(&alignment.transform);
            (p.accurate(&alignment.transform), rot, rms)
        }
        None => (false, 0.0, 0.0),
    };
    PairRecord {
        building: truth.map_or("negative".to_string(), |p| p.building.clone()),
        negative: truth.is_none(),
        accepted: alignment.accepted,
        accurate,
        rot_err_deg: rot,
        rms_px: rms,
        src: src.to_string(),
        dst: dst.to_string(),
        alignment,
        ms,
        accurate_candidates,
    }
}

/// A pair set's pairs, then its negatives, in the order [`run`] aligns them: (src, dst, the truth).
type Job<'a> = (&'a str, &'a str, Option<&'a TruePair>);

fn jobs(set: &PairSet) -> Vec<Job<'_>> {
    set.pairs
        .iter()
        .map(|p| (p.src.as_str(), p.dst.as_str(), Some(p)))
        .chain(
            set.negatives
                .iter()
                .map(|n| (n.src.as_str(), n.dst.as_str(), None)),
        )
        .collect()
}

/// Each map's last job.
fn last_uses<'a>(jobs: &[Job<'a>]) -> HashMap<&'a str, usize> {
    let mut last = HashMap::new();
    for (k, (src, dst, _)) in jobs.iter().enumerate() {
        last.insert(*src, k);
        last.insert(*dst, k);
    }
    last
}

/// The most bytes [`run`] holds at once over `set`, from each map's bytes (`bytes(name)`: the map and its
/// preparation): a map is held from its first pair to its last. With the number of maps then held.
pub fn peak_held(set: &PairSet, bytes: &dyn Fn(&str) -> Result<u64>) -> Result<(u64, usize)> {
    let jobs = jobs(set);
    let last = last_uses(&jobs);
    let mut held: HashMap<&str, u64> = HashMap::new();
    let (mut peak, mut most) = (0u64, 0usize);
    for (k, (src, dst, _)) in jobs.iter().enumerate() {
        for name in [*src, *dst] {
            if !held.contains_key(name) {
                held.insert(name, bytes(name)?);
            }
        }
        let total = held.values().fold(0u64, |a, &b| a.saturating_add(b));
        if total > peak {
            (peak, most) = (total, held.len());
        }
        held.retain(|name, _| last[name] > k);
    }
    Ok((peak, most))
}

/// Runs the merger on synthetic pairs cut from each of `sources` ([`synthetic_pair`]) as `run` says:
/// `per_map` pairs per map and overlap, named `<map>/<overlap>/<k>` (grouped by overlap; k's parity splits
/// the halves), and, with `negatives`, per overlap one negative per map: A cut from it, B from the next
/// map.
pub fn run_synthetic(
    sources: &[(String, OccupancyMap)],
    run: &SyntheticRun,
    options: &MergeOptions,
) -> Result<(Vec<PairRecord>, MapCosts)> {
    run_synthetic_with(sources, run, options, &mut |_, _, _, _, _| Ok(()))
}

/// [`run_synthetic`], showing each pair to `on_pair` as it is done.
pub fn run_synthetic_with(
    sources: &[(String, OccupancyMap)],
    run: &SyntheticRun,
    options: &MergeOptions,
    on_pair: &mut OnPair,
) -> Result<(Vec<PairRecord>, MapCosts)> {
    let SyntheticRun {
        overlaps,
        per_map,
        noise,
        seed,
        negatives,
        furnished,
        save,
    } = run;
    let (per_map, noise, seed, negatives) = (*per_map, *noise, *seed, *negatives);
    let mut saved: Vec<TruePair> = Vec::new();
    let mut out = Vec::new();
    let mut prep = PrepTimer::default();
    // A cut pair written (when saving), run, shown and kept.
    let mut take = |label: String,
                    group: &str,
                    pair: &SyntheticPair,
                    out: &mut Vec<PairRecord>,
                    prep: &mut PrepTimer,
                    on_pair: &mut OnPair|
     -> Result<()> {
        let stem = saved_stem(&label);
        // The truth as a pair file holds it, named as saved maps are, with its building.
        let building = synthetic_building(&label);
        let truth = pair.true_pair(&format!("b_{stem}"), &format!("a_{stem}"), building);
        if let Some(dir) = save {
            pair.a
                .image
                .write_pgm(&dir.join(format!("{}.pgm", truth.dst)))?;
            pair.b
                .image
                .write_pgm(&dir.join(format!("{}.pgm", truth.src)))?;
        }
        let record = synthetic_record(label, group, false, pair, &truth, options, prep);
        on_pair(out.len(), &record, &pair.a, &pair.b, Some(truth.truth()))?;
        out.push(record);
        if save.is_some() {
            saved.push(truth);
        }
        Ok(())
    };
    for &overlap in overlaps.iter() {
        let spec = SyntheticSpec { overlap, noise };
        let group = format!("synthetic, {:.0}% overlap", 100.0 * overlap);
        let mut cuts = Vec::new();
        for (i, (name, map)) in sources.iter().enumerate() {
            for k in 0..per_map {
                let s = seed
                    .wrapping_mul(1_000_003)
                    .wrapping_add((i * 7919 + k) as u64)
                    .wrapping_add((overlap * 1e4) as u64);
                let Some(pair) = synthetic_pair(map, &spec, s) else {
                    continue;
                };
                take(
                    synthetic_label(name, overlap, k),
                    &group,
                    &pair,
                    &mut out,
                    &mut prep,
                    on_pair,
                )?;
                if k == 0 {
                    cuts.push((name.clone(), pair));
                }
            }
        }
        // Negatives: A of one map against B of the next.
        if negatives && cuts.len() >= 2 {
            run_negatives(&cuts, overlap, options, &mut prep, on_pair, &mut out)?;
        }
    }
    // Each plan against its furnished copy: A a window of the plan, B one of the copy.
    for (name, copy) in furnished {
        let Some((i, (_, plan))) = sources.iter().enumerate().find(|(_, (n, _))| n == name) else {
            continue;
        };
        for k in 0..per_map {
            let s = seed
                .wrapping_mul(1_000_033)
                .wrapping_add((i * 7919 + k) as u64);
            if let Some(pair) = furnished_pair(plan, copy, noise, s) {
                take(
                    furnished_label(name, k),
                    FURNISHED_GROUP,
                    &pair,
                    &mut out,
                    &mut prep,
                    on_pair,
                )?;
            }
        }
    }
    if let Some(dir) = save {
        write_pair_file(dir, &saved)?;
    }
    Ok((out, prep.costs()))
}

/// The negatives of one overlap: A of each cut against B of the next map's, run, shown and kept.
fn run_negatives(
    cuts: &[(String, SyntheticPair)],
    overlap: f64,
    options: &MergeOptions,
    prep: &mut PrepTimer,
    on_pair: &mut OnPair,
    out: &mut Vec<PairRecord>,
) -> Result<()> {
    for i in 0..cuts.len() {
        let (na, a) = (&cuts[i].0, &cuts[i].1.a);
        let (nb, b) = (
            &cuts[(i + 1) % cuts.len()].0,
            &cuts[(i + 1) % cuts.len()].1.b,
        );
        let (pa, pb) = (prep.prepare(a), prep.prepare(b));
        let (alignment, ms) = prep.align(&pa, &pb, options);
        let alignment = alignment
            .unwrap_or_else(|e| crate::merge::pair::align::declined(&format!("refused: {e}")));
        let record = PairRecord {
            src: format!("{nb}/{:.0}/b", 100.0 * overlap),
            dst: format!("{na}/{:.0}/a", 100.0 * overlap),
            building: "negative".to_string(),
            negative: true,
            accepted: alignment.accepted,
            accurate: false,
            rot_err_deg: 0.0,
            rms_px: 0.0,
            alignment,
            ms,
            accurate_candidates: Vec::new(),
        };
        on_pair(out.len(), &record, a, b, None)?;
        out.push(record);
    }
    Ok(())
}

/// The saved pairs' truths as a pair file in `dir`, its maps beside it, as it says: `merge-eval
/// DIR/pairs.json` finds them.
fn write_pair_file(dir: &std::path::Path, saved: &[TruePair]) -> Result<()> {
    let set = serde_json::json!({ "pairs": saved, "negatives": [], "maps": "." });
    let text = serde_json::to_string_pretty(&set)
        .map_err(|e| crate::support::error::Error::Internal(e.to_string()))?;
    crate::support::files::write_atomic(&dir.join("pairs.json"), |w| {
        w.write_all(text.as_bytes())?;
        writeln!(w)
    })
}

/// Maps prepared for the merger, timed: the synthetic runs prepare both maps of every pair anew.
#[derive(Default)]
pub(crate) struct PrepTimer {
    ms: f64,
    maps: usize,
    symmetry_ms: f64,
    symmetric: usize,
}

impl PrepTimer {
    /// `m` prepared, its time counted.
    pub(crate) fn prepare(&mut self, m: &OccupancyMap) -> Prepared {
        self.timed(|| Prepared::new(m))
    }

    /// `m` prepared with the corners of `detector` when the hypotheses need them, its time counted.
    pub(crate) fn prepare_with(
        &mut self,
        m: &OccupancyMap,
        detector: Option<DetectorKind>,
    ) -> Result<Prepared> {
        self.timed(|| match detector {
            Some(d) => Prepared::with_corners(m, d),
            None => Ok(Prepared::new(m)),
        })
    }

    /// One map's preparation, `make`, timed and counted.
    fn timed<T>(&mut self, make: impl FnOnce() -> T) -> T {
        let t = Instant::now();
        let p = make();
        self.ms += t.elapsed().as_secs_f64() * 1e3;
        self.maps += 1;
        p
    }

    /// `align_prepared(a, b, options)` and its time, milliseconds, less the self-symmetry it measured
    /// for either map (counted here per map: it is cached, so only the first pair that needs it pays).
    pub(crate) fn align(
        &mut self,
        a: &Prepared,
        b: &Prepared,
        options: &MergeOptions,
    ) -> (Result<Alignment>, f64) {
        // The same map as both (a self-alignment) counts once.
        let maps: Vec<&Prepared> = if std::ptr::eq(a, b) {
            vec![a]
        } else {
            vec![a, b]
        };
        let before: Vec<bool> = maps.iter().map(|p| p.symmetry.get().is_some()).collect();
        let t = Instant::now();
        let alignment = align_prepared(a, b, options);
        let mut ms = t.elapsed().as_secs_f64() * 1e3;
        for (p, had) in maps.into_iter().zip(before) {
            if let (false, Some(s)) = (had, p.symmetry.get()) {
                self.symmetry_ms += s.ms;
                self.symmetric += 1;
                ms -= s.ms;
            }
        }
        (alignment, ms.max(0.0))
    }

    /// What the maps cost, once each.
    pub(crate) fn costs(&self) -> MapCosts {
        MapCosts {
            prepare_ms: self.ms / self.maps.max(1) as f64,
            symmetry_ms: self.symmetry_ms / self.symmetric.max(1) as f64,
            symmetric_maps: self.symmetric,
            maps: self.maps,
        }
    }
}

/// What maps cost once each, apart from the pairs' align times (mean milliseconds a map): preparation
/// (every map) and the self-symmetry (measured only for a map in a pair the rule could accept; cached).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct MapCosts {
    /// Preparing a map for alignment.
    pub prepare_ms: f64,
    /// Measuring a map's self-symmetry, over the maps that needed it.
    pub symmetry_ms: f64,
    /// Maps whose self-symmetry was measured.
    pub symmetric_maps: usize,
    /// Maps prepared.
    pub maps: usize,
}

impl MapCosts {
    /// Two runs' costs together (means weighted by their maps).
    pub fn and(self, o: MapCosts) -> MapCosts {
        let mean = |x: f64, n: usize, y: f64, m: usize| {
            (x * n as f64 + y * m as f64) / (n + m).max(1) as f64
        };
        MapCosts {
            prepare_ms: mean(self.prepare_ms, self.maps, o.prepare_ms, o.maps),
            symmetry_ms: mean(
                self.symmetry_ms,
                self.symmetric_maps,
                o.symmetry_ms,
                o.symmetric_maps,
            ),
            symmetric_maps: self.symmetric_maps + o.symmetric_maps,
            maps: self.maps + o.maps,
        }
    }
}

/// The merger on one synthetic pair (both maps prepared by `prep`), recorded against `truth`; a
/// `negative` pair (parts that do not overlap) is wrong whenever accepted.
pub(crate) fn synthetic_record(
    label: String,
    group: &str,
    negative: bool,
    pair: &SyntheticPair,
    truth: &TruePair,
    options: &MergeOptions,
    prep: &mut PrepTimer,
) -> PairRecord {
    let (pa, pb) = (prep.prepare(&pair.a), prep.prepare(&pair.b));
    let (alignment, ms) = prep.align(&pa, &pb, options);
    let alignment =
        alignment.unwrap_or_else(|e| crate::merge::pair::align::declined(&format!("refused: {e}")));
    let (rot, rms) = truth.errors(&alignment.transform);
    let accurate_candidates = alignment
        .candidates
        .iter()
        .map(|c| !negative && truth.accurate(&c.transform))
        .collect();
    PairRecord {
        src: label.clone(),
        dst: label,
        building: group.to_string(),
        negative,
        accepted: alignment.accepted,
        accurate: !negative && truth.accurate(&alignment.transform),
        rot_err_deg: rot,
        rms_px: rms,
        alignment,
        ms,
        accurate_candidates,
    }
}

/// How [`run_synthetic`] cuts and runs its pairs.
#[derive(Clone, Debug)]
pub struct SyntheticRun {
    /// The overlaps, each a share in (0, 1).
    pub overlaps: Vec<f64>,
    /// Pairs per map and overlap.
    pub per_map: usize,
    /// Speckle probability.
    pub noise: f64,
    /// Seed of the cuts.
    pub seed: u64,
    /// One negative per map and overlap (only for sources known to be different places).
    pub negatives: bool,
    /// Furnished copies of sources (the same place in the same frame with furniture drawn in), each
    /// under its source's name: `per_map` plan-vs-furnished pairs each ([`furnished_pair`]), named
    /// `<map>+furnished/<k>`.
    pub furnished: Vec<NamedMap>,
    /// Write every pair there (`a_<stem>.pgm`, `b_<stem>.pgm`) with a `pairs.json` of their truths, which
    /// `merge-eval DIR/pairs.json` reads back.
    pub save: Option<std::path::PathBuf>,
}

/// A map and its name.
pub type NamedMap = (String, OccupancyMap);

/// What a map named `NAME_furnished` beside a map `NAME` is: its furnished copy (the maps-more layout).
pub const FURNISHED_SUFFIX: &str = "_furnished";

/// The group of the plan-vs-furnished pairs in a summary.
pub const FURNISHED_GROUP: &str = "plan vs furnished";

/// `sources` split into the maps cut on their own and the furnished copies ([`SyntheticRun::furnished`]):
/// a map named `NAME_furnished` when a map `NAME` is among them goes under `NAME`.
pub fn furnished_copies(sources: Vec<NamedMap>) -> (Vec<NamedMap>, Vec<NamedMap>) {
    let names: std::collections::HashSet<String> = sources.iter().map(|(n, _)| n.clone()).collect();
    let (mut own, mut copies) = (Vec::new(), Vec::new());
    for (name, map) in sources {
        match name.strip_suffix(FURNISHED_SUFFIX) {
            Some(base) if names.contains(base) => copies.push((base.to_string(), map)),
            _ => own.push((name, map)),
        }
    }
    (own, copies)
}

/// A plan-vs-furnished pair's name: `<map>+furnished/<k>`.
pub fn furnished_label(map: &str, k: usize) -> String {
    format!("{map}+furnished/{k}")
}

/// The building a synthetic pair's name names: its map (`<map>[+furnished]/...`).
pub fn synthetic_building(label: &str) -> &str {
    let map = label.split('/').next().unwrap_or(label);
    map.strip_suffix("+furnished").unwrap_or(map)
}

/// A synthetic pair's name: `<map>/<overlap percent>/<k>`.
pub fn synthetic_label(map: &str, overlap: f64, k: usize) -> String {
    format!("{map}/{:.0}/{k}", 100.0 * overlap)
}

/// The file stem a saved synthetic pair's maps get: its label with anything but letters, digits, `-`,
/// `_` and `.` turned into `-`.
pub fn saved_stem(label: &str) -> String {
    label
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "-_.".contains(c) {
                c
            } else {
                '-'
            }
        })
        .collect()
}

/// The hypothesis sources [`ablation`] compares: dense alone, then corners alone and both, per detector.
pub fn ablation_modes() -> Vec<Hypotheses> {
    let detectors = [
        DetectorKind::Ogm,
        DetectorKind::OgmRobust,
        DetectorKind::Baseline(Baseline::Harris),
        DetectorKind::Baseline(Baseline::ShiTomasi),
        DetectorKind::Baseline(Baseline::Trajkovic),
    ];
    std::iter::once(Hypotheses::Dense)
        .chain(detectors.iter().map(|&d| Hypotheses::Corners(d)))
        .chain(detectors.iter().map(|&d| Hypotheses::Both(d)))
        .collect()
}

/// One row of [`ablation`].
#[derive(Clone, Debug, Serialize)]
pub struct AblationRow {
    /// The hypothesis source ([`Hypotheses::name`]).
    pub hypotheses: String,
    /// Pairs of one place.
    pub pairs: usize,
    /// Accepted and accurate.
    pub accepted_accurate: usize,
    /// Accurate if all were accepted.
    pub accurate: usize,
    /// An accurate transform among the refined candidates.
    pub found: usize,
    /// Accepted and not accurate.
    pub wrong: usize,
    /// Pairs of different places accepted.
    pub negatives_accepted: usize,
    /// Median time of `align` a pair, milliseconds.
    pub median_ms: f64,
    /// Mean time to prepare a map (corner detection included), milliseconds.
    pub prepare_ms: f64,
}

/// Runs the merger over `set` once per hypothesis source of [`ablation_modes`], the acceptance rule as
/// calibrated for dense hypotheses; `progress` hears of each source as it starts.
pub fn ablation(
    set: &PairSet,
    maps: &Path,
    progress: &mut dyn FnMut(&str),
) -> Result<Vec<AblationRow>> {
    let mut out = Vec::new();
    for h in ablation_modes() {
        progress(&h.name());
        let options = MergeOptions {
            hypotheses: h,
            ..MergeOptions::default()
        };
        let (rows, costs) = run(set, maps, &options)?;
        let pos: Vec<&PairRecord> = rows.iter().filter(|r| !r.negative).collect();
        let mut ms: Vec<f64> = pos.iter().map(|r| r.ms).collect();
        ms.sort_by(f64::total_cmp);
        out.push(AblationRow {
            hypotheses: h.name(),
            pairs: pos.len(),
            accepted_accurate: pos.iter().filter(|r| r.accepted && r.accurate).count(),
            accurate: pos.iter().filter(|r| r.accurate).count(),
            found: pos
                .iter()
                .filter(|r| r.accurate_candidates.iter().any(|&a| a))
                .count(),
            wrong: pos.iter().filter(|r| r.accepted && !r.accurate).count(),
            negatives_accepted: rows.iter().filter(|r| r.negative && r.accepted).count(),
            median_ms: ms.get(ms.len() / 2).copied().unwrap_or(0.0),
            prepare_ms: costs.prepare_ms,
        });
    }
    Ok(out)
}

/// The ablation as a markdown table.
pub fn write_ablation(out: &mut dyn Write, rows: &[AblationRow]) -> io::Result<()> {
    writeln!(
        out,
        "| hypotheses | accepted and accurate | accurate if all accepted | accurate among the candidates | wrong accepts | negatives accepted | median ms | prepare ms |"
    )?;
    writeln!(out, "|---|---|---|---|---|---|---|---|")?;
    for r in rows {
        let pct = |k: usize| 100.0 * k as f64 / r.pairs.max(1) as f64;
        writeln!(
            out,
            "| {} | {} ({:.1}%) | {} ({:.1}%) | {} ({:.1}%) | {} | {} | {:.0} | {:.0} |",
            r.hypotheses,
            r.accepted_accurate,
            pct(r.accepted_accurate),
            r.accurate,
            pct(r.accurate),
            r.found,
            pct(r.found),
            r.wrong,
            r.negatives_accepted,
            r.median_ms,
            r.prepare_ms
        )?;
    }
    Ok(())
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
pub fn write_summary(out: &mut dyn Write, rows: &[PairRecord], costs: &MapCosts) -> io::Result<()> {
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
        "| building | pairs | accepted and accurate | accurate if all accepted | accurate among the candidates | wrong accepts | median ms | p90 ms |"
    )?;
    writeln!(out, "|---|---|---|---|---|---|---|---|")?;
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
        let found = sel
            .iter()
            .filter(|r| r.accurate_candidates.iter().any(|&a| a))
            .count();
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
            "| {} | {n} | {ok} ({:.1}%) | {could} ({:.1}%) | {found} ({:.1}%) | {wrong} | {:.0} | {:.0} |",
            crate::detect::output::md_cell(g),
            pct(ok),
            pct(could),
            pct(found),
            q(0.5),
            q(0.9)
        )?;
    }
    writeln!(
        out,
        "\nPreparing a map (once per map): {:.0} ms on average. Its self-symmetry (once per map, for the \
         {} of {} maps in a pair the rule could accept; not in the pairs' times): {:.0} ms on average.",
        costs.prepare_ms, costs.symmetric_maps, costs.maps, costs.symmetry_ms
    )?;
    writeln!(
        out,
        "\nOperating curve: the acceptance rule's threshold moved by an offset (0 is the default; the \
         vetoes hold throughout: fine conflict at most {}, contradiction at most {}, self-match at most \
         {}):\n",
        crate::merge::pair::align::MAX_FINE_CONFLICT,
        crate::merge::pair::align::MAX_CONTRADICTION,
        crate::merge::pair::align::MAX_SELF_SYMMETRY
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
pub const CURVE_OFFSETS: [f64; 11] = [-8.0, -4.0, -2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0, 4.0, 8.0];

/// For each offset of [`CURVE_OFFSETS`] added to the rule's threshold: accepted pairs of one place,
/// accepted and accurate ones, wrong accepts among them, and accepted negatives.
pub fn operating_curve(rows: &[PairRecord]) -> Vec<(f64, usize, usize, usize, usize)> {
    CURVE_OFFSETS
        .iter()
        .map(|&o| {
            let acc = |r: &&PairRecord| {
                crate::merge::pair::align::accepts(&r.alignment.features, r.alignment.score - o)
            };
            let pos: Vec<&PairRecord> = rows.iter().filter(|r| !r.negative).filter(acc).collect();
            let negatives = rows.iter().filter(|r| r.negative).filter(acc).count();
            let correct = pos.iter().filter(|r| r.accurate).count();
            (o, pos.len(), correct, pos.len() - correct, negatives)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A map is held from its first pair to its last: a set of cut pairs (each map once) holds two maps
    /// at a time, a hub map named by every pair stays throughout.
    #[test]
    fn a_pair_set_holds_each_map_from_its_first_pair_to_its_last() {
        let pair = |src: &str, dst: &str| {
            format!(
                r#"{{"src": "{src}", "dst": "{dst}", "theta_deg": 0, "tx": 0, "ty": 0, "rms_limit_px": 3,
                "rot_limit_deg": 2, "src_points": [[0, 0]], "dst_points": [[0, 0]]}}"#
            )
        };
        let set = |pairs: &[(&str, &str)]| -> PairSet {
            let list: Vec<String> = pairs.iter().map(|(s, d)| pair(s, d)).collect();
            serde_json::from_str(&format!(r#"{{"pairs": [{}]}}"#, list.join(","))).unwrap()
        };
        let one = |_: &str| Ok(1u64);
        let cut = set(&[("b1", "a1"), ("b2", "a2"), ("b3", "a3")]);
        assert_eq!(peak_held(&cut, &one).unwrap(), (2, 2));
        let hub = set(&[("b", "a"), ("c", "a"), ("d", "a"), ("d", "e")]);
        assert_eq!(peak_held(&hub, &one).unwrap(), (2, 2));
        let ring = set(&[("b", "a"), ("c", "b"), ("a", "c")]);
        assert_eq!(peak_held(&ring, &one).unwrap(), (3, 3));
    }

    /// The self-symmetry that a pair's alignment measures is counted once per map, out of the pair's
    /// time; a second pair of the same maps and a map aligned with itself add what they should.
    #[test]
    fn self_symmetry_is_counted_once_per_map_apart_from_the_pairs() {
        let office =
            OccupancyMap::from_image(crate::map::synthetic::office_map(480, 360, 5).unwrap());
        let spec = SyntheticSpec {
            overlap: 0.6,
            noise: 0.0,
        };
        let pair = synthetic_pair(&office, &spec, 3).unwrap();
        let options = MergeOptions {
            always_verify: true,
            ..MergeOptions::default()
        };
        let mut timer = PrepTimer::default();
        let (a, b) = (timer.prepare(&pair.a), timer.prepare(&pair.b));
        let (first, ms) = timer.align(&a, &b, &options);
        first.unwrap();
        let c = timer.costs();
        assert_eq!((c.maps, c.symmetric_maps), (2, 2), "{c:?}");
        assert!(c.symmetry_ms > 0.0 && ms >= 0.0, "{c:?} {ms}");
        // Cached in the maps: the pair the other way measures nothing more.
        timer.align(&b, &a, &options).0.unwrap();
        assert_eq!(timer.costs().symmetric_maps, 2);
        // A map aligned with itself is one map.
        let lone = timer.prepare(&pair.a);
        timer.align(&lone, &lone, &options).0.unwrap();
        assert_eq!(timer.costs().symmetric_maps, 3);
        assert_eq!(timer.costs().maps, 3);
    }
}
