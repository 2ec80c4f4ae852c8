//! The hard synthetic families of `merge-eval --synthetic`, each with exact truth from the project's own
//! generators: repetitive layouts (a grid of equal rooms, warehouse aisles, a corridor of identical
//! doors) at 50, 30 and 20% overlap; bent maps (heading drift, speckle, unexplored rooms); small partial
//! maps (windows of 120 to 400 px, overlapping or apart); symmetric halls (2 to 8 identical wings,
//! mirrored or not, one with an extra room) cut into two windows that both hold the hall. The halls with
//! an extra room are reported by whether both windows hold the room (the one detail that tells their
//! turns apart), with as many pairs again drawn until both do.
//!
//! A repetitive pair is reported in its own row when nothing in its overlap breaks the period
//! ([`SyntheticPair::alias_contradiction`] under [`MIN_ALIAS_CONTRADICTION`]): no merger can tell its
//! true pose from a wrong one, so declining it is right and only a wrong accept counts against the
//! merger. Windows apart are negatives: any accept is wrong.

use crate::map::OccupancyMap;
use crate::measure::merging::{
    synthetic_label, synthetic_record, MapCosts, OnPair, PairRecord, PrepTimer,
};
use crate::measure::synthetic::{
    extra_room_in_both, extra_room_turns_seen, hall_pair, hall_pair_holding_room, synthetic_crops,
    synthetic_pair_with, CropSpec, LayoutKind, PairShape, SymmetricKind, SyntheticPair,
    SyntheticSpec, MIN_ALIAS_CONTRADICTION,
};
use crate::merge::pair::align::MergeOptions;
use crate::support::error::{Error, Result};

/// A family of synthetic pairs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Family {
    /// One of the repetitive layouts.
    Layout(LayoutKind),
    /// Offices with B bent by heading drift, speckled and partly unexplored.
    Bent,
    /// Small windows of offices, overlapping or apart.
    Crops,
    /// Symmetric halls ([`SymmetricKind::suite`]): two windows that both hold the hall.
    Symmetric,
}

impl Family {
    /// Every family, in report order.
    pub fn all() -> Vec<Family> {
        LayoutKind::ALL
            .iter()
            .map(|&k| Family::Layout(k))
            .chain([Family::Bent, Family::Crops, Family::Symmetric])
            .collect()
    }

    /// Its name in reports and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Family::Layout(k) => k.name(),
            Family::Bent => "bent",
            Family::Crops => "crops",
            Family::Symmetric => "symmetric",
        }
    }

    /// The family called `name`.
    pub fn parse(name: &str) -> Result<Family> {
        Family::all()
            .into_iter()
            .find(|f| f.name() == name)
            .ok_or_else(|| {
                let names: Vec<&str> = Family::all().iter().map(|f| f.name()).collect();
                Error::invalid(format!(
                    "unknown synthetic family {name:?}: expected office or one of {}",
                    names.join(", ")
                ))
            })
    }
}

/// Overlaps of the repetitive families.
pub const LAYOUT_OVERLAPS: [f64; 3] = [0.5, 0.3, 0.2];
/// Overlaps of the bent family.
pub const BENT_OVERLAPS: [f64; 2] = [0.5, 0.3];
/// The bent family's heading drift, degrees per 1000 px (its speckle and unexplored share below).
pub const BENT_DRIFT: f64 = 4.0;
const BENT_NOISE: f64 = 0.002;
const BENT_UNEXPLORED: f64 = 0.08;
/// Window sides of the crops family, pixels.
pub const CROP_SIDES: [u32; 3] = [120, 250, 400];
/// Overlaps of the crops family (`None`: apart).
pub const CROP_OVERLAPS: [Option<f64>; 3] = [Some(0.5), Some(0.3), None];

/// A family's row at overlap `o`: `<name>, <percent>% overlap`.
fn overlap_group(name: &str, o: f64) -> String {
    format!("{name}, {:.0}% overlap", 100.0 * o)
}

/// What a family's draw hands on for each pair: its label, its group, whether it is a negative, the pair.
type Push<'a> = dyn FnMut(String, String, bool, SyntheticPair) -> Result<()> + 'a;

/// Runs `per` pairs of each of `families` and each of its overlaps, deterministic in `seed`; the mean
/// preparation time of a map, ms. Each pair is drawn, aligned and let go before the next is drawn.
pub fn run_families(
    families: &[Family],
    per: usize,
    seed: u64,
    options: &MergeOptions,
    on_pair: &mut OnPair,
) -> Result<(Vec<PairRecord>, MapCosts)> {
    let mut out = Vec::new();
    let mut prep = PrepTimer::default();
    let offices: Vec<OccupancyMap> = (0..per as u64)
        .map(|k| {
            crate::map::synthetic::office_map(1024, 768, seed.wrapping_mul(97).wrapping_add(k + 11))
                .map(OccupancyMap::from_image)
        })
        .collect::<Result<_>>()?;
    let mut push =
        |label: String, group: String, negative: bool, pair: SyntheticPair| -> Result<()> {
            let truth = pair.true_pair(&label, &label, &group);
            let r = synthetic_record(label, &group, negative, &pair, &truth, options, &mut prep);
            on_pair(out.len(), &r, &pair.a, &pair.b, Some(truth.truth()))?;
            out.push(r);
            Ok(())
        };
    for &family in families {
        let name = family.name();
        match family {
            Family::Layout(kind) => layout_pairs(name, kind, per, seed, &mut push)?,
            Family::Bent => bent_pairs(name, &offices, seed, &mut push)?,
            Family::Crops => crop_pairs(name, &offices, seed, &mut push)?,
            Family::Symmetric => symmetric_pairs(name, per, seed, &mut push)?,
        }
    }
    Ok((out, prep.costs()))
}

/// A layout family's pairs: `per` layouts at each overlap, grouped by whether the overlap breaks the
/// layout's period.
fn layout_pairs(
    name: &str,
    kind: LayoutKind,
    per: usize,
    seed: u64,
    push: &mut Push,
) -> Result<()> {
    for &o in &LAYOUT_OVERLAPS {
        for k in 0..per {
            let s = seed.wrapping_mul(7919).wrapping_add(k as u64);
            let layout = kind.make(s)?;
            let map = OccupancyMap::from_image(layout.image);
            let shape = PairShape {
                lattice: layout.lattice,
                ..PairShape::default()
            };
            let spec = SyntheticSpec {
                overlap: o,
                noise: 0.0,
            };
            let Some(pair) = synthetic_pair_with(&map, &spec, &shape, s ^ (o * 1e4) as u64) else {
                continue;
            };
            let breaks = pair.alias_contradiction.unwrap_or(u64::MAX) >= MIN_ALIAS_CONTRADICTION;
            let group = if breaks {
                overlap_group(name, o)
            } else {
                format!("{}, nothing breaks the period", overlap_group(name, o))
            };
            push(synthetic_label(name, o, k), group, false, pair)?;
        }
    }
    Ok(())
}

/// The bent family's pairs: each office at each overlap, bent, speckled and partly unexplored.
fn bent_pairs(name: &str, offices: &[OccupancyMap], seed: u64, push: &mut Push) -> Result<()> {
    for &o in &BENT_OVERLAPS {
        for (k, map) in offices.iter().enumerate() {
            let shape = PairShape {
                bend_deg_per_kpx: BENT_DRIFT,
                unexplored: BENT_UNEXPLORED,
                ..PairShape::default()
            };
            let spec = SyntheticSpec {
                overlap: o,
                noise: BENT_NOISE,
            };
            let s = seed
                .wrapping_mul(31)
                .wrapping_add(k as u64 * 101 + (o * 1e4) as u64);
            let Some(pair) = synthetic_pair_with(map, &spec, &shape, s) else {
                continue;
            };
            push(
                synthetic_label(name, o, k),
                overlap_group(name, o),
                false,
                pair,
            )?;
        }
    }
    Ok(())
}

/// The crops family's pairs: square windows of each side, overlapping or apart (negatives).
fn crop_pairs(name: &str, offices: &[OccupancyMap], seed: u64, push: &mut Push) -> Result<()> {
    for &side in &CROP_SIDES {
        for &o in &CROP_OVERLAPS {
            for (k, map) in offices.iter().enumerate() {
                let spec = CropSpec {
                    side,
                    overlap: o,
                    noise: 0.0,
                };
                let s = seed
                    .wrapping_mul(131)
                    .wrapping_add(k as u64 * 1009 + u64::from(side))
                    .wrapping_add(o.map_or(7, |o| (o * 1e4) as u64));
                let Some(pair) = synthetic_crops(map, &spec, s) else {
                    continue;
                };
                let (group, what) = match o {
                    Some(o) => (
                        format!("{name} {side} px, {:.0}% overlap", 100.0 * o),
                        format!("{:.0}", 100.0 * o),
                    ),
                    None => (
                        format!("{name} {side} px, apart (negative)"),
                        "apart".to_string(),
                    ),
                };
                push(
                    format!("{name}/{side}/{what}/{k}"),
                    group,
                    o.is_none(),
                    pair,
                )?;
            }
        }
    }
    Ok(())
}

/// The group of a pair whose windows both hold the extra room: apart by whether the other window has
/// seen where each turn by a whole wing would lay the room's door ([`extra_room_turns_seen`]), the
/// pairs a merger can tell from their turns at all.
fn in_both(kind: SymmetricKind, seed: u64, pair: &SyntheticPair) -> String {
    if extra_room_turns_seen(kind, seed, pair) {
        format!("{}, in both windows, its turns seen", kind.name())
    } else {
        format!("{}, in both windows, a turn unseen", kind.name())
    }
}

/// The symmetric family's pairs: `per` halls of each kind, the extra-room ones grouped by whether both
/// windows hold the room, and as many again drawn until both do.
fn symmetric_pairs(name: &str, per: usize, seed: u64, push: &mut Push) -> Result<()> {
    let label =
        |what: &str, k: String| format!("{name}/{}/{k}", what.replace(", ", "-").replace(' ', "-"));
    for kind in SymmetricKind::suite() {
        for k in 0..per {
            let s = seed
                .wrapping_mul(613)
                .wrapping_add(k as u64 * 17 + u64::from(kind.wings));
            let Some(pair) = hall_pair(kind, s) else {
                continue;
            };
            // The extra-room pairs apart by whether the one detail that tells the turns apart lies in
            // both windows.
            let what = match (kind.extra_room, extra_room_in_both(kind, s, &pair)) {
                (false, _) => kind.name(),
                (true, true) => in_both(kind, s, &pair),
                (true, false) => format!("{}, not in both", kind.name()),
            };
            push(
                label(&what, k.to_string()),
                format!("{name}: {what}"),
                false,
                pair,
            )?;
            if let Some((pair, held)) = hall_pair_holding_room(kind, s ^ 0x600d_4004) {
                let what = in_both(kind, held, &pair);
                push(
                    label(&what, format!("held-{k}")),
                    format!("{name}: {what}"),
                    false,
                    pair,
                )?;
            }
        }
    }
    Ok(())
}
