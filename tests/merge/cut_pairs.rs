//! Pair sets cut from any maps for `merge-eval`: each cut pair's truth checked by an independent
//! computation (the truth carries B's walls onto A's walls, pixel by pixel), the plan-vs-furnished pairs'
//! windows and truth, and the sets written by `--save-pairs` run again from their pair file with each
//! pair named by its building.

use crate::common;
use common::run::*;

use ogm_corners::map::synthetic::{office_map, FREE, OCCUPIED, UNKNOWN};
use ogm_corners::measure::synthetic::{
    furnished_pair, synthetic_pair, SyntheticPair, SyntheticSpec, FURNISHED_MIN_SHARED,
    FURNISHED_PART,
};
use ogm_corners::merge::Rigid;
use ogm_corners::{MapImage, OccupancyMap};

/// The share of `from`'s wall pixels that land, by `t`, on a wall pixel of `onto` (within one pixel),
/// among those that land on its known area; and how many landed there.
fn walls_on_walls(from: &MapImage, onto: &MapImage, t: &Rigid) -> (f64, usize) {
    let (w, h) = (onto.width() as i64, onto.height() as i64);
    let (mut landed, mut on_wall) = (0usize, 0usize);
    for y in 0..from.height() {
        for x in 0..from.width() {
            if from.get(x, y) != OCCUPIED {
                continue;
            }
            let (px, py) = t.apply((f64::from(x), f64::from(y)));
            let (px, py) = (px.round() as i64, py.round() as i64);
            if px < 1 || py < 1 || px >= w - 1 || py >= h - 1 {
                continue;
            }
            if onto.get(px as u32, py as u32) == UNKNOWN {
                continue;
            }
            landed += 1;
            let near_wall = (-1..=1).any(|dy| {
                (-1..=1).any(|dx| onto.get((px + dx) as u32, (py + dy) as u32) == OCCUPIED)
            });
            on_wall += usize::from(near_wall);
        }
    }
    (on_wall as f64 / landed.max(1) as f64, landed)
}

#[test]
fn a_cut_pairs_truth_carries_b_walls_onto_a_walls() {
    for seed in 0..6u64 {
        let map = OccupancyMap::from_image(office_map(640, 480, seed + 3).unwrap());
        for overlap in [0.5, 0.3] {
            let spec = SyntheticSpec {
                overlap,
                noise: 0.0,
            };
            let pair = synthetic_pair(&map, &spec, seed * 17 + 1).unwrap();
            let (share, landed) = walls_on_walls(&pair.b.image, &pair.a.image, &pair.truth);
            assert!(
                landed > 200,
                "seed {seed}: only {landed} walls in the overlap"
            );
            assert!(
                share > 0.97,
                "seed {seed}, {overlap}: {share:.3} of {landed}"
            );
            // A wrong transform does not: the check can fail.
            let off = Rigid {
                tx: pair.truth.tx + 9.0,
                ..pair.truth
            };
            let (wrong, _) = walls_on_walls(&pair.b.image, &pair.a.image, &off);
            assert!(wrong < share - 0.1, "seed {seed}: {wrong:.3} vs {share:.3}");
        }
    }
}

/// An office and its furnished copy: the same walls, with desks (boxes of wall) in its rooms.
fn furnished(seed: u64) -> (OccupancyMap, OccupancyMap) {
    let plan = office_map(640, 480, seed).unwrap();
    let mut copy = plan.clone();
    let mut rng = ogm_corners::map::synthetic::Rng::new(seed);
    let (w, h) = (plan.width(), plan.height());
    for _ in 0..400 {
        let (x0, y0) = (rng.range(2, w - 12), rng.range(2, h - 12));
        let (bw, bh) = (rng.range(4, 10), rng.range(4, 10));
        let all_free =
            (y0 - 2..y0 + bh + 2).all(|y| (x0 - 2..x0 + bw + 2).all(|x| plan.get(x, y) == FREE));
        if !all_free {
            continue;
        }
        for y in y0..y0 + bh {
            for x in x0..x0 + bw {
                let edge = x == x0 || y == y0 || x == x0 + bw - 1 || y == y0 + bh - 1;
                copy.pixels_mut()[(y * w + x) as usize] = if edge { OCCUPIED } else { UNKNOWN };
            }
        }
    }
    (
        OccupancyMap::from_image(plan),
        OccupancyMap::from_image(copy),
    )
}

fn known(m: &MapImage) -> usize {
    m.pixels().iter().filter(|&&v| v != UNKNOWN).count()
}

#[test]
fn a_plan_against_its_furnished_copy_is_cut_into_two_windows_with_exact_truth() {
    for seed in 1..7u64 {
        let (plan, copy) = furnished(seed);
        let pair: SyntheticPair = furnished_pair(&plan, &copy, 0.0, seed).unwrap();
        // The plan's walls stand in the copy too: A's walls land on B's walls by the inverse truth.
        let back = pair.truth.inverse();
        let (share, landed) = walls_on_walls(&pair.a.image, &pair.b.image, &back);
        assert!(landed > 200, "seed {seed}: {landed}");
        assert!(share > 0.97, "seed {seed}: {share:.3} of {landed}");
        // B holds furniture A does not have: the copy, not the plan, was cut for B.
        let (b_on_a, _) = walls_on_walls(&pair.b.image, &pair.a.image, &pair.truth);
        assert!(b_on_a < share, "seed {seed}: {b_on_a:.3} vs {share:.3}");
        // Each window holds 36-64% of the known area (A's is read before B is turned and resampled).
        let total = known(&plan.image) as f64;
        let a_share = known(&pair.a.image) as f64 / total;
        assert!(
            (FURNISHED_PART.0 - 0.02..=FURNISHED_PART.1 + 0.02).contains(&a_share),
            "seed {seed}: A holds {a_share:.3}"
        );
        // Both hold at least FURNISHED_MIN_SHARED of the known area (less what furniture hides in B).
        let mut both = 0usize;
        for y in 0..pair.a.image.height() {
            for x in 0..pair.a.image.width() {
                if pair.a.image.get(x, y) == UNKNOWN {
                    continue;
                }
                let (bx, by) = back.apply((f64::from(x), f64::from(y)));
                let (bx, by) = (bx.round() as i64, by.round() as i64);
                let inside = bx >= 0
                    && by >= 0
                    && bx < i64::from(pair.b.image.width())
                    && by < i64::from(pair.b.image.height());
                both += usize::from(inside && pair.b.image.get(bx as u32, by as u32) != UNKNOWN);
            }
        }
        let shared = both as f64 / total;
        assert!(
            shared > FURNISHED_MIN_SHARED - 0.05,
            "seed {seed}: the windows share {shared:.3}"
        );
        // The same seed, the same pair.
        let again = furnished_pair(&plan, &copy, 0.0, seed).unwrap();
        assert_eq!(again.truth, pair.truth);
        assert_eq!(again.a.image, pair.a.image);
    }
    // A copy of another size is no copy.
    let (plan, _) = furnished(1);
    let other = OccupancyMap::from_image(office_map(600, 480, 1).unwrap());
    assert!(furnished_pair(&plan, &other, 0.0, 1).is_none());
}

/// `merge-eval --synthetic PLAN COPY --furnished --save-pairs DIR --format json`, then the saved pair file
/// again: the same pairs, named by their building, with the same verdicts.
fn saved_set_runs_again(maps: &[&std::path::Path], building: &str) {
    let d = tmp();
    let sp = d.path().join("sp");
    let mut args = vec!["merge-eval", "--synthetic"];
    args.extend(maps.iter().map(|p| s(p)));
    args.extend([
        "--furnished",
        "--per-map",
        "1",
        "--save-pairs",
        s(&sp),
        "--format",
        "json",
    ]);
    let o = ogm(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let first: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let labels: Vec<&str> = first
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["src"].as_str().unwrap())
        .collect();
    assert!(
        labels.contains(&format!("{building}+furnished/0").as_str()),
        "{labels:?}"
    );
    // The copy is not cut on its own.
    assert!(
        labels.iter().all(|l| !l.contains("_furnished")),
        "{labels:?}"
    );
    let set: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(sp.join("pairs.json")).unwrap()).unwrap();
    let pairs = set["pairs"].as_array().unwrap();
    assert_eq!(pairs.len(), labels.len());
    assert!(pairs.iter().all(|p| p["building"] == building), "{set}");
    let again = ogm_json(&["merge-eval", s(&sp.join("pairs.json")), "--format", "json"]);
    let verdicts = |v: &serde_json::Value| -> Vec<(bool, bool)> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|r| {
                (
                    r["accepted"].as_bool().unwrap(),
                    r["accurate"].as_bool().unwrap(),
                )
            })
            .collect()
    };
    assert_eq!(verdicts(&first), verdicts(&again));
}

#[test]
fn plan_vs_furnished_pairs_are_saved_and_run_again_by_building() {
    let d = tmp();
    let (plan, copy) = furnished(2);
    let (p, c) = (
        d.path().join("hall.pgm"),
        d.path().join("hall_furnished.pgm"),
    );
    plan.image.write_pgm(&p).unwrap();
    copy.image.write_pgm(&c).unwrap();
    saved_set_runs_again(&[&p, &c], "hall");
    // Without a copy beside it, --furnished is refused.
    refused(
        &ogm(&["merge-eval", "--synthetic", s(&p), "--furnished"]),
        "_furnished",
    );
}

#[test]
fn the_maps_more_plans_and_their_furnished_copies_make_pairs() {
    let Some(more) = common::maps_more() else {
        return;
    };
    let ipa = more.join("ipa");
    saved_set_runs_again(
        &[
            &ipa.join("lab_a_scan.yaml"),
            &ipa.join("lab_a_scan_furnished.yaml"),
        ],
        "lab_a_scan",
    );
}

/// Leave-one-building-out over several pair files at once (two Halmstad buildings and a saved set of
/// maps-more cuts): one row per building of every file, each with its declines counted by reason, the
/// declines whose best candidate was right, the candidate recall and the shipped rule beside the fold's.
#[test]
fn cross_validation_takes_several_pair_files_and_reports_each_building() {
    let (Some(halmstad), Some(more)) = (common::merge_pairs(), common::maps_more()) else {
        return;
    };
    let d = tmp();
    let sp = d.path().join("more");
    let ipa = more.join("ipa");
    let o = ogm(&[
        "merge-eval",
        "--synthetic",
        s(&ipa.join("lab_a_scan.yaml")),
        s(&ipa.join("lab_a_scan_furnished.yaml")),
        s(&ipa.join("office_b.yaml")),
        "--furnished",
        "--per-map",
        "1",
        "--save-pairs",
        s(&sp),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rows = ogm_json(&[
        "merge-eval",
        "--cross-validate",
        s(&halmstad.join("pairs.json")),
        s(&sp.join("pairs.json")),
        "--only",
        "HIH,KPT4A,a_,b_",
        "--format",
        "json",
    ]);
    let rows = rows.as_array().unwrap();
    let names: Vec<&str> = rows
        .iter()
        .map(|r| r["building"].as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        [
            "HIH",
            "KPT4A",
            "lab_a_scan",
            "office_b",
            "pooled held-out",
            "in-sample (fitted on all)",
            "shipped rule, all"
        ]
    );
    let n = |r: &serde_json::Value, k: &str| r[k].as_u64().unwrap();
    for r in rows {
        assert_eq!(
            n(r, "accepted_accurate") + n(r, "wrong") + n(r, "declined"),
            n(r, "pairs"),
            "{r}"
        );
        let reasons: u64 = r["reasons"]
            .as_object()
            .unwrap()
            .values()
            .map(|v| v.as_u64().unwrap())
            .sum();
        assert_eq!(reasons, n(r, "declined"), "{r}");
        assert!(n(r, "found_turned_down") <= n(r, "declined"), "{r}");
        assert!(
            n(r, "right_among_candidates") >= n(r, "accepted_accurate"),
            "{r}"
        );
    }
    assert_eq!(n(&rows[0], "pairs"), 12);
    assert_eq!(
        n(&rows[2], "pairs"),
        3,
        "two cuts and one plan-vs-furnished pair"
    );
    // The shipped rule's row is the shipped rule beside itself.
    let shipped = &rows[6];
    assert_eq!(
        n(shipped, "accepted_accurate"),
        n(shipped, "shipped_accepted_accurate")
    );
    // A table a person reads: the reasons named as the why: lines open them.
    let o = ogm(&["merge-eval", "--cross-validate", s(&sp.join("pairs.json"))]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("found and turned down"),
        "{}",
        stdout(&o)
    );
    // Several pair files outside --cross-validate are refused.
    refused(
        &ogm(&[
            "merge-eval",
            s(&sp.join("pairs.json")),
            s(&sp.join("pairs.json")),
        ]),
        "only --cross-validate",
    );
}

/// The on-disk cache of measured alignments: a second run reads every pair back with the same records, a
/// changed map is measured again (and only its pair), and another build's entries are not read.
#[test]
fn measured_pairs_are_kept_and_found_again_until_a_map_or_the_code_changes() {
    let d = tmp();
    let (plan, copy) = furnished(3);
    let (p, c) = (
        d.path().join("hall.pgm"),
        d.path().join("hall_furnished.pgm"),
    );
    plan.image.write_pgm(&p).unwrap();
    copy.image.write_pgm(&c).unwrap();
    let sp = d.path().join("sp");
    let o = ogm(&[
        "merge-eval",
        "--synthetic",
        s(&p),
        s(&c),
        "--furnished",
        "--per-map",
        "1",
        "--save-pairs",
        s(&sp),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let cache = d.path().join("cache");
    let run = || {
        let o = ogm(&[
            "merge-eval",
            s(&sp.join("pairs.json")),
            "--cache",
            s(&cache),
            "--format",
            "json",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        let rows: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
        (rows, stderr(&o))
    };
    let (first, e) = run();
    let n = first.as_array().unwrap().len();
    assert_eq!(n, 3);
    assert!(e.contains("0 pairs read from the cache"), "{e}");
    assert!(e.contains(&format!("{n} aligned")), "{e}");
    let (again, e) = run();
    assert!(e.contains(&format!("{n} pairs read from the cache")), "{e}");
    assert!(e.contains("0 aligned"), "{e}");
    assert_eq!(first, again);
    // One map changed (a wall pixel more): its pair is measured again, the others are read.
    let set: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(sp.join("pairs.json")).unwrap()).unwrap();
    let dst = set["pairs"][0]["dst"].as_str().unwrap();
    let path = sp.join(format!("{dst}.pgm"));
    let mut m = OccupancyMap::load(&path).unwrap();
    let i = m.image.pixels().iter().position(|&v| v == FREE).unwrap();
    m.image.pixels_mut()[i] = OCCUPIED;
    m.image.write_pgm(&path).unwrap();
    let (_, e) = run();
    assert!(
        e.contains(&format!("{} pairs read from the cache", n - 1)),
        "{e}"
    );
    assert!(e.contains("1 aligned"), "{e}");
    // --no-cache reads and writes nothing.
    let o = ogm(&["merge-eval", s(&sp.join("pairs.json")), "--no-cache"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("cache"), "{}", stderr(&o));
    // Another build of the measuring code finds nothing of this one's.
    use ogm_corners::measure::merging::cache::RecordCache;
    use ogm_corners::merge::MergeOptions;
    let options = MergeOptions::default();
    let al = ogm_corners::merge::align(&plan, &copy, &options).unwrap();
    let mut one = RecordCache::for_build(&cache, "build one");
    let key = one.key_of(&plan, &copy, &options);
    one.put(&key, &al, 1.0);
    assert_eq!(one.get(&key).map(|(a, _)| a), Some(al.clone()));
    let mut two = RecordCache::for_build(&cache, "build two");
    assert_ne!(two.key_of(&plan, &copy, &options), key);
    assert!(two.get(&key).is_none());
    // A damaged entry is measured again, not an error.
    std::fs::write(cache.join(format!("{key}.json")), "{ not json").unwrap();
    assert!(one.get(&key).is_none());
}

/// The symmetric family's pairs: each kind's truth carries B's walls onto A's, over a large shared part
/// (both windows hold the hall), and a pose a few pixels off does not.
#[test]
fn a_symmetric_halls_pairs_have_exact_truths() {
    use ogm_corners::measure::synthetic::{hall_pair, SymmetricKind};
    for kind in SymmetricKind::suite() {
        let pair = hall_pair(kind, 5).unwrap();
        let (share, landed) = walls_on_walls(&pair.b.image, &pair.a.image, &pair.truth);
        assert!(landed > 500, "{kind:?}: {landed}");
        assert!(share > 0.97, "{kind:?}: {share:.3} of {landed}");
        let off = Rigid {
            tx: pair.truth.tx + 9.0,
            ..pair.truth
        };
        let (wrong, _) = walls_on_walls(&pair.b.image, &pair.a.image, &off);
        assert!(wrong < share - 0.1, "{kind:?}: {wrong:.3} vs {share:.3}");
    }
}

/// The symmetric family's pairs drawn until both windows hold the extra room: they do (the room's
/// centre and corners free in A, and in B where the truth puts them), their truths are exact, and the
/// family's plain draws do not always (so the test that tells them apart is not always true).
#[test]
fn a_hall_pair_holding_its_room_holds_it_in_both_windows() {
    use ogm_corners::measure::synthetic::{
        extra_room_in_both, extra_room_points, hall_pair, hall_pair_holding_room, hall_pixel,
        symmetric_plan, SymmetricKind,
    };
    let plain = SymmetricKind::plain(4);
    assert!(hall_pair_holding_room(plain, 1).is_none());
    for kind in SymmetricKind::suite().into_iter().filter(|k| k.extra_room) {
        for seed in 1..=3u64 {
            let (pair, s) = hall_pair_holding_room(kind, seed).unwrap();
            assert!(extra_room_in_both(kind, s, &pair), "{kind:?} {seed}");
            let (_, hall) = symmetric_plan(kind, s).unwrap();
            assert_eq!(hall_pixel(kind, s), hall, "{kind:?} {seed}");
            for (u, v) in extra_room_points(kind, s).unwrap() {
                let a = (hall.0 + u - pair.a_origin.0, hall.1 + v - pair.a_origin.1);
                let b = pair.truth.inverse().apply(a);
                assert_eq!(
                    pair.a.image.get(a.0.round() as u32, a.1.round() as u32),
                    FREE
                );
                assert_eq!(
                    pair.b.image.get(b.0.round() as u32, b.1.round() as u32),
                    FREE
                );
            }
            let (share, _) = walls_on_walls(&pair.b.image, &pair.a.image, &pair.truth);
            assert!(share > 0.97, "{kind:?} {seed}: {share:.3}");
        }
        let held = (1..=16u64)
            .filter(|&s| hall_pair(kind, s).is_some_and(|p| extra_room_in_both(kind, s, &p)))
            .count();
        assert!(held < 16, "{kind:?}: every plain draw holds the room");
    }
}
