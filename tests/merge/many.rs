//! Many maps placed at once (`merge A B C ...`, `ogm_corners::merge::many`): synthetic sets with exact
//! truth, a wrong pairwise accept repaired by cycles, unrelated sets kept apart, determinism, the CLI and
//! its outputs, and the real buildings when the shared data is there.

use crate::common;
use ogm_corners::backend::reference::ReferenceBackend;
use ogm_corners::measure::merging::many::{run_maps, score, synthetic_maps, synthetic_maps_of};
use ogm_corners::measure::pairs::TruePair;
use ogm_corners::merge::many::graph::Placement;
use ogm_corners::merge::many::{align_all, place, GlobalOptions, Pairwise};
use ogm_corners::merge::pair::align::Prepared;
use ogm_corners::merge::Rigid;
use ogm_corners::{MapImage, OccupancyMap};

/// Every ordered pair of `truths` among placed maps: the placement's implied transform within `rot` deg
/// and `rms` px of the truth at the check points. Returns how many were checked.
fn assert_placed_within(
    names: &[String],
    poses: &[Option<Rigid>],
    truths: &[TruePair],
    rot: f64,
    rms: f64,
) -> usize {
    let at = |n: &str| names.iter().position(|x| x == n).unwrap();
    let mut checked = 0;
    for t in truths {
        let (Some(s), Some(d)) = (poses[at(&t.src)], poses[at(&t.dst)]) else {
            continue;
        };
        let (r, e) = t.errors(&d.inverse().after(&s));
        assert!(
            r <= rot && e <= rms,
            "{} -> {}: {r:.2} deg, {e:.2} px off",
            t.src,
            t.dst
        );
        checked += 1;
    }
    checked
}

#[test]
fn synthetic_sets_are_placed_within_a_pixel_and_half_a_degree() {
    for (n, seed) in [(3, 2), (6, 5), (10, 9)] {
        let (names, maps, truths) = synthetic_maps(n, seed).unwrap();
        let r = run_maps(names.clone(), &maps, &GlobalOptions::default(), &|_, _| {}).unwrap();
        let poses = placed_poses(&r.placement);
        // One group holding every map.
        assert_eq!(r.placement.groups.len(), 1, "{n} maps: {:?}", r.placement);
        assert!(
            poses.iter().all(Option::is_some),
            "{n} maps: {:?}",
            r.placement.maps
        );
        let checked = assert_placed_within(&names, &poses, &truths, 0.5, 1.0);
        assert_eq!(checked, n * (n - 1));
        assert_eq!(r.pairwise.pairs.len(), n * (n - 1) / 2);
    }
}

/// Windows of the office generator drawn at its own scale (rooms of 20-40 px: each window a grid of small
/// alike rooms). The pair test used to accept wrong poses here that leave a fifth of their walls in the
/// other map's free space, as real maps' right poses may, and the set's own level (measured on its pairs
/// that cycles confirm, under 1% here) excluded them: before the level, 3 of the 7 maps placed were
/// placed wrongly. Since the alternative poses include each map's turns and the search's turned
/// candidates, the pair test accepts none of them (without its symmetry checks it accepts 56 wrong here,
/// too many for the level: the checks are the first line, the level the second, whose exclusion the
/// calibration's own tests cover). A map that repeats itself keeps the self-match veto whatever its
/// listed alternatives show: judged pose by pose, the groups' mosaics were merged a room off and 8 of 17
/// maps placed wrongly.
#[test]
fn a_set_of_small_alike_rooms_is_never_placed_wrongly() {
    use ogm_corners::measure::merging::many::SetResult;
    use ogm_corners::merge::many::{run_cached, Cache};
    let office =
        OccupancyMap::from_image(ogm_corners::map::synthetic::office_map(512, 384, 1).unwrap());
    let (names, maps, truths) = synthetic_maps_of(&office, 20, 1).unwrap();
    // Every pair aligned; the maps' preparations and the pairs' alignments are kept for the screened
    // run below (the screen does not change them, only which pairs it reads).
    let mut cache = Cache::new();
    let run = |options: &GlobalOptions, cache: &mut Cache| {
        let r = run_cached(&maps, options, &mut ReferenceBackend, &|_, _| {}, cache).unwrap();
        SetResult::of(names.clone(), r)
    };
    let r = run(&GlobalOptions::with_partners(0), &mut cache);
    let row = score("own scale", &r, &truths, &|_| "synthetic".to_string());
    assert_eq!(row.pairwise_wrong, 0, "{row:?}");
    let level = r.placement.level;
    assert!(
        level.limit.is_some_and(|l| l < 0.1) && level.median < 0.01,
        "{level:?}"
    );
    assert_eq!(row.wrong, 0, "{row:?}");
    assert!(row.placed >= 8 && row.derived_wrong == 0, "{row:?}");
    // Screened (the default for 20 maps): no map placed wrongly either.
    let r = run(&GlobalOptions::default(), &mut cache);
    assert_eq!(cache.last_use().pairs_aligned, 0);
    let row = score("own scale", &r, &truths, &|_| "synthetic".to_string());
    assert!(row.wrong == 0 && row.derived_wrong == 0, "{row:?}");
}

/// Each map's pose, when placed.
fn placed_poses(p: &Placement) -> Vec<Option<Rigid>> {
    p.maps.iter().map(|m| m.group.map(|_| m.pose)).collect()
}

fn prepare(maps: &[OccupancyMap]) -> Vec<Prepared> {
    maps.iter().map(Prepared::new).collect()
}

#[test]
fn a_wrong_pairwise_accept_is_dropped_by_the_cycles_and_the_placement_is_repeatable() {
    let (names, maps, truths) = synthetic_maps(5, 4).unwrap();
    let prepared = prepare(&maps);
    let refs: Vec<&OccupancyMap> = maps.iter().collect();
    let options = GlobalOptions::default();
    let pairwise = align_all(&prepared, &options, &|_, _| {}).unwrap();
    let placed = place(&pairwise, &prepared, &refs, &options, &mut ReferenceBackend).unwrap();
    // Deterministic: the same placement again, to the bit.
    assert_eq!(
        placed,
        place(&pairwise, &prepared, &refs, &options, &mut ReferenceBackend).unwrap()
    );
    let again = align_all(&prepared, &options, &|_, _| {}).unwrap();
    assert_eq!(
        serde_json::to_string(&again).unwrap(),
        serde_json::to_string(&pairwise).unwrap()
    );
    // Inject a confident wrong accept: the choice of the most confident pair turned by 90 degrees about
    // the moved map's overlap and shifted, with a rule value above every real one.
    let mut bad: Pairwise = pairwise.clone();
    let i = (0..bad.edges.len())
        .filter(|&i| bad.edges[i].accepted)
        .max_by(|&x, &y| bad.edges[x].score.total_cmp(&bad.edges[y].score))
        .unwrap();
    let top = bad.edges.iter().map(|e| e.score).fold(f64::MIN, f64::max);
    let e = &mut bad.edges[i];
    let c = e.at;
    let turn = Rigid {
        theta_deg: 90.0,
        tx: c.0 + c.1 + 150.0,
        ty: c.1 - c.0,
    };
    e.transform = e.transform.after(&turn);
    e.score = top + 20.0;
    let (wrong_a, wrong_b) = (e.a, e.b);
    let placed = place(&bad, &prepared, &refs, &options, &mut ReferenceBackend).unwrap();
    let poses = placed_poses(&placed);
    assert!(poses.iter().all(Option::is_some), "{:?}", placed.maps);
    assert_placed_within(&names, &poses, &truths, 0.5, 1.0);
    assert!(
        placed
            .dropped
            .iter()
            .any(|d| (d.edge.a, d.edge.b) == (wrong_a, wrong_b)),
        "{:?}",
        placed.dropped
    );
}

#[test]
fn cycles_and_the_mosaic_place_a_map_whose_pairs_no_pair_test_accepted() {
    let (names, maps, truths) = synthetic_maps(5, 4).unwrap();
    let prepared = prepare(&maps);
    let refs: Vec<&OccupancyMap> = maps.iter().collect();
    let options = GlobalOptions::default();
    let mut pairwise = align_all(&prepared, &options, &|_, _| {}).unwrap();
    // Every pair of the last map declined, as if each pair test had been unsure.
    let last = maps.len() - 1;
    let mut demoted = 0;
    for e in pairwise.edges.iter_mut().filter(|e| e.b == last) {
        demoted += usize::from(e.accepted);
        e.accepted = false;
    }
    for p in pairwise.pairs.iter_mut().filter(|p| p.b == last) {
        p.accepted = false;
    }
    assert!(
        demoted >= 2,
        "the set should give the last map two accepted pairs"
    );
    let placed = place(&pairwise, &prepared, &refs, &options, &mut ReferenceBackend).unwrap();
    let poses = placed_poses(&placed);
    assert!(poses[last].is_some(), "{:?}", placed.maps[last]);
    assert!(placed
        .kept
        .iter()
        .any(|&i| pairwise.edges[i].b == last && !pairwise.edges[i].accepted));
    assert_placed_within(&names, &poses, &truths, 0.5, 1.0);
}

#[test]
fn maps_of_unrelated_places_form_separate_groups_and_a_lone_map_is_not_placed() {
    let (mut names, mut maps, _) = synthetic_maps(3, 11).unwrap();
    let (other_names, other_maps, _) = synthetic_maps(3, 12).unwrap();
    names.extend(other_names.iter().map(|n| format!("other-{n}")));
    maps.extend(other_maps);
    // A blank map overlaps nothing.
    names.push("blank".to_string());
    maps.push(OccupancyMap::from_image(
        MapImage::filled(200, 200, 254).unwrap(),
    ));
    let r = run_maps(names, &maps, &GlobalOptions::default(), &|_, _| {}).unwrap();
    let groups: Vec<Option<usize>> = r.placement.maps.iter().map(|m| m.group).collect();
    assert_eq!(r.placement.groups.len(), 2, "{groups:?}");
    assert!(groups[..3].iter().all(|g| *g == groups[0] && g.is_some()));
    assert!(groups[3..6].iter().all(|g| *g == groups[3] && g.is_some()));
    assert_ne!(groups[0], groups[3]);
    assert_eq!(groups[6], None);
    assert!(r.placement.maps[6].reason.is_some());
}

fn write_map(dir: &std::path::Path, name: &str, map: &OccupancyMap, resolution: f64) {
    map.image
        .write_pgm(&dir.join(format!("{name}.pgm")))
        .unwrap();
    std::fs::write(
        dir.join(format!("{name}.yaml")),
        format!("image: {name}.pgm\nresolution: {resolution}\norigin: [-1.0, 2.0, 0.0]\n"),
    )
    .unwrap();
}

#[test]
fn merge_command_places_many_maps_and_writes_every_output() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path().join("fleet");
    std::fs::create_dir(&dir).unwrap();
    let (names, maps, _) = synthetic_maps(4, 3).unwrap();
    for (n, m) in names.iter().zip(&maps) {
        write_map(&dir, n, m, 0.05);
    }
    MapImage::filled(120, 120, 205)
        .unwrap()
        .write_pgm(&d.path().join("unknown.pgm"))
        .unwrap();
    let run = |args: &[&str]| common::tool_in(d.path(), "merge", args);
    let o = run(&[
        "fleet",
        "unknown.pgm",
        "-o",
        "merged.yaml",
        "--overlay",
        "merged.png",
        "--poses",
        "poses.json",
        "--init-poses",
        "init.yaml",
    ]);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("4 of 5 maps placed in 1 group(s)"), "{text}");
    assert!(text.contains("unknown.pgm: not placed: "), "{text}");
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.path().join("poses.json")).unwrap()).unwrap();
    let entries = v["maps"].as_array().unwrap();
    assert_eq!(entries.len(), 5);
    let merged = OccupancyMap::load(d.path().join("merged.yaml")).unwrap();
    let first = OccupancyMap::load(dir.join(format!("{}.yaml", names[0]))).unwrap();
    for e in entries {
        if e["map"].as_str().unwrap().ends_with("unknown.pgm") {
            assert_eq!(e["placed"], false);
            assert!(e["group"].is_null());
            assert!(e["reason"].as_str().is_some_and(|r| !r.is_empty()));
            continue;
        }
        assert_eq!(e["placed"], true, "{e}");
        assert_eq!(e["group"], 0);
        for k in ["theta_deg", "tx", "ty"] {
            assert!(e["transform"][k].is_f64(), "{e}");
        }
        for k in ["yaw", "x", "y"] {
            assert!(e["world"][k].is_f64(), "{e}");
        }
    }
    // The first map's transform into the merged map is a pure shift, and its cells keep their world
    // coordinates in the merged yaml.
    let t = &entries[0]["transform"];
    assert!(t["theta_deg"].as_f64().unwrap().abs() < 1e-9);
    let (tx, ty) = (t["tx"].as_f64().unwrap(), t["ty"].as_f64().unwrap());
    let (g, g0) = (merged.georef.unwrap(), first.georef.unwrap());
    let p = g.pixel_to_world(tx.round() as u32, ty.round() as u32, merged.image.height());
    let q = g0.pixel_to_world(0, 0, first.image.height());
    assert!((p.0 - q.0).abs() < 1e-6 && (p.1 - q.1).abs() < 1e-6);
    assert!(d.path().join("merged.pgm").is_file());
    assert!(d.path().join("merged.png").is_file());
    let init = std::fs::read_to_string(d.path().join("init.yaml")).unwrap();
    let y: serde_yaml::Value = serde_yaml::from_str(&init).unwrap();
    for n in &names {
        assert!(
            y[n.as_str()]["map_merge"]["init_pose_yaw"].is_f64(),
            "{init}"
        );
    }
    assert!(init.contains("# unknown: not placed"), "{init}");
    // JSON on standard output: the same document.
    let o = run(&["fleet", "--format", "json"]);
    assert_eq!(o.status.code(), Some(0));
    let w: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(w["maps"].as_array().unwrap().len(), 4);
    // The same file twice: both placed, at the same pose.
    let a = format!("fleet/{}.yaml", names[0]);
    let b = format!("fleet/{}.yaml", names[1]);
    let o = run(&[&a, &a, &b, "--format", "json"]);
    assert_eq!(o.status.code(), Some(0));
    let w: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(w["maps"][0]["transform"], w["maps"][1]["transform"]);
    // Three copies of one map: one group, in place (as `merge X X` merges at the identity); of a map
    // with nothing to align, none.
    let o = run(&[&a, &a, &a, "--format", "json"]);
    assert_eq!(o.status.code(), Some(0));
    let w: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(w["groups"].as_array().unwrap().len(), 1, "{w}");
    assert_eq!(w["maps"][2]["copy_of"], a.as_str());
    let o = run(&["unknown.pgm", "unknown.pgm", "unknown.pgm"]);
    assert_eq!(o.status.code(), Some(3));
    // Nothing in common: exit 3 with the verdict.
    MapImage::filled(90, 90, 254)
        .unwrap()
        .write_pgm(&d.path().join("free.pgm"))
        .unwrap();
    let o = run(&["unknown.pgm", "free.pgm", &a]);
    assert_eq!(
        o.status.code(),
        Some(3),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    // An output that cannot be written leaves none of the others; a missing output folder is refused
    // before the work.
    #[cfg(target_os = "linux")]
    {
        let o = run(&[
            "fleet",
            "-o",
            "w.yaml",
            "--overlay",
            "w.png",
            "--poses",
            "/dev/full",
        ]);
        assert_eq!(o.status.code(), Some(1));
        for f in ["w.yaml", "w.pgm", "w.png"] {
            assert!(!d.path().join(f).exists(), "{f} left behind");
        }
    }
    let o = run(&["fleet", "--overlay", "nowhere/x.png"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("folder does not exist"));
    // Bad input: exit 2, one line, nothing written.
    for args in [
        vec!["fleet", "missing.pgm"],
        vec!["unknown.pgm"],
        vec!["fleet", "-o", "m.txt"],
        vec!["fleet", "--poses", "fleet/part-00.pgm"],
    ] {
        let o = run(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        assert_eq!(
            String::from_utf8_lossy(&o.stderr).lines().count(),
            1,
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
}

#[test]
fn maps_of_different_resolutions_are_placed_at_the_first_maps_resolution() {
    let d = tempfile::tempdir().unwrap();
    let (names, maps, truths) = synthetic_maps(3, 6).unwrap();
    write_map(d.path(), &names[0], &maps[0], 0.05);
    write_map(d.path(), &names[1], &maps[1], 0.05);
    // The third at half the resolution: every other pixel.
    let m = &maps[2].image;
    let (w, h) = (m.width() / 2, m.height() / 2);
    let px = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| m.get(2 * x, 2 * y))
        .collect();
    let coarse = OccupancyMap::from_image(MapImage::new(w, h, px).unwrap());
    write_map(d.path(), &names[2], &coarse, 0.1);
    let o = common::tool_in(d.path(), "merge", &[".", "--format", "json"]);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let entries = v["maps"].as_array().unwrap();
    assert!(entries.iter().all(|e| e["placed"] == true), "{v}");
    let third = entries
        .iter()
        .find(|e| e["map"].as_str().unwrap().contains(&names[2]))
        .unwrap();
    assert_eq!(third["scale"].as_f64(), Some(2.0));
    // Its world pose agrees with the truth to within a coarse pixel.
    let t = truths
        .iter()
        .find(|t| t.src == names[2] && t.dst == names[0])
        .unwrap();
    let first = entries
        .iter()
        .find(|e| e["map"].as_str().unwrap().contains(&names[0]))
        .unwrap();
    let yaw = |e: &serde_json::Value| e["world"]["yaw"].as_f64().unwrap();
    let turn = (yaw(third) - yaw(first)).to_degrees() + t.theta_deg;
    assert!(
        (turn + 180.0).rem_euclid(360.0) - 180.0 < 0.5,
        "{turn}: {third} {first}"
    );
}

#[test]
fn the_real_buildings_are_placed_whole_and_never_into_each_other() {
    let Some(dir) = common::merge_pairs() else {
        return;
    };
    let set = ogm_corners::measure::pairs::PairSet::load(&dir.join("pairs.json")).unwrap();
    // Two maps of each apartment: maps of one place give alike wrong answers for a map of another, and
    // their agreeing votes must not join the two.
    let four: Vec<String> = ["HIH_01", "HIH_02", "KPT4A_01", "KPT4A_02"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    let maps: Vec<OccupancyMap> = four
        .iter()
        .map(|n| OccupancyMap::load(dir.join("maps").join(format!("{n}.png"))).unwrap())
        .collect();
    let r = run_maps(four, &maps, &GlobalOptions::default(), &|_, _| {}).unwrap();
    let g: Vec<Option<usize>> = r.placement.maps.iter().map(|m| m.group).collect();
    assert!(g[0] != g[2] || g[0].is_none(), "{g:?}");
    assert!(g[1] != g[3] || g[1].is_none(), "{g:?}");
    // The two apartments (8 maps, 28 pairs): quick enough for every run; F5 is `merge-eval --global`'s.
    let names: Vec<String> = ["HIH", "KPT4A"]
        .iter()
        .flat_map(|b| (1..=4).map(move |k| format!("{b}_{k:02}")))
        .collect();
    let maps: Vec<OccupancyMap> = names
        .iter()
        .map(|n| OccupancyMap::load(dir.join("maps").join(format!("{n}.png"))).unwrap())
        .collect();
    let r = run_maps(names.clone(), &maps, &GlobalOptions::default(), &|_, _| {}).unwrap();
    let groups: Vec<Option<usize>> = r.placement.maps.iter().map(|m| m.group).collect();
    // Measured: each apartment one group of 4 (docs/merging.md, "Merging many maps").
    assert_eq!(r.placement.groups.len(), 2, "{groups:?}");
    assert!(groups[..4].iter().all(|g| g.is_some() && *g == groups[0]));
    assert!(groups[4..].iter().all(|g| g.is_some() && *g == groups[4]));
    let poses = placed_poses(&r.placement);
    for t in &set.pairs {
        let (Some(s), Some(d)) = (
            names.iter().position(|n| *n == t.src),
            names.iter().position(|n| *n == t.dst),
        ) else {
            continue;
        };
        let est = poses[d].unwrap().inverse().after(&poses[s].unwrap());
        assert!(t.accurate(&est), "{} -> {}", t.src, t.dst);
    }
}

/// A live merge places the same maps again and again while a few change: the cache hands back each
/// unchanged map's preparation and each unchanged pair's alignment, and the placement is the one a fresh
/// run gives, to the bit. A changed map (one wall pixel) is prepared again with its pairs, and a map
/// given twice is still aligned once.
#[test]
fn a_cached_run_redoes_only_the_changed_maps_and_pairs_and_equals_a_fresh_run() {
    use ogm_corners::merge::many::{run, run_cached, Cache, CacheUse};
    let (_, mut maps, _) = synthetic_maps(5, 4).unwrap();
    let options = GlobalOptions::default();
    let same = |a: &ogm_corners::merge::many::Run, b: &ogm_corners::merge::many::Run| {
        assert_eq!(
            serde_json::to_string(&a.pairwise).unwrap(),
            serde_json::to_string(&b.pairwise).unwrap()
        );
        assert_eq!(a.placement, b.placement);
    };
    let mut cache = Cache::new();
    let first = run_cached(
        &maps,
        &options,
        &mut ReferenceBackend,
        &|_, _| {},
        &mut cache,
    )
    .unwrap();
    same(
        &first,
        &run(&maps, &options, &mut ReferenceBackend, &|_, _| {}).unwrap(),
    );
    let use_of = |r, p, rr, a| CacheUse {
        maps_reused: r,
        maps_prepared: p,
        pairs_reused: rr,
        pairs_aligned: a,
        pairs_refused: 0,
    };
    assert_eq!(cache.last_use(), use_of(0, 5, 0, 10));
    let again = run_cached(
        &maps,
        &options,
        &mut ReferenceBackend,
        &|_, _| {},
        &mut cache,
    )
    .unwrap();
    same(&again, &first);
    assert_eq!(cache.last_use(), use_of(5, 0, 10, 0));
    // Map 2 changes by one pixel: it and its four pairs are redone, nothing else.
    let px = maps[2].image.pixels_mut();
    let i = px.iter().position(|&v| v > 250).unwrap();
    px[i] = 0;
    let changed = run_cached(
        &maps,
        &options,
        &mut ReferenceBackend,
        &|_, _| {},
        &mut cache,
    )
    .unwrap();
    assert_eq!(cache.last_use(), use_of(4, 1, 6, 4));
    same(
        &changed,
        &run(&maps, &options, &mut ReferenceBackend, &|_, _| {}).unwrap(),
    );
    // A sixth map that copies the first: no new preparation, no new pair; placed with its first copy.
    maps.push(maps[0].clone());
    let copied = run_cached(
        &maps,
        &options,
        &mut ReferenceBackend,
        &|_, _| {},
        &mut cache,
    )
    .unwrap();
    assert_eq!(cache.last_use(), use_of(5, 0, 10, 0));
    same(
        &copied,
        &run(&maps, &options, &mut ReferenceBackend, &|_, _| {}).unwrap(),
    );
    // Other options: nothing is reused.
    let other = GlobalOptions {
        loop_px: options.loop_px + 1.0,
        ..options
    };
    run_cached(&maps, &other, &mut ReferenceBackend, &|_, _| {}, &mut cache).unwrap();
    assert_eq!(cache.last_use(), use_of(0, 5, 0, 10));
    // Another pre-screen only: a preparation and an alignment do not depend on it, everything is reused.
    let unscreened = GlobalOptions {
        prescreen: None,
        ..other
    };
    run_cached(
        &maps,
        &unscreened,
        &mut ReferenceBackend,
        &|_, _| {},
        &mut cache,
    )
    .unwrap();
    assert_eq!(cache.last_use(), use_of(5, 0, 10, 0));
}

/// A large set is screened: each map aligned first with its most similar maps, then the pairs that close
/// cycles. Two offices of 8 maps each (16, over the 12 that align every pair): every map placed within
/// the synthetic limits, the offices apart, and far fewer pairs aligned than all 120.
#[test]
fn a_screened_set_places_every_map_with_a_fraction_of_the_pairs() {
    use ogm_corners::measure::merging::many::synthetic_mixed;
    use ogm_corners::merge::many::{run_cached, Cache};
    let (names, maps, truths) = synthetic_mixed(16, 2, 3).unwrap();
    let mut cache = Cache::new();
    let r = run_cached(
        &maps,
        &GlobalOptions::default(),
        &mut ReferenceBackend,
        &|_, _| {},
        &mut cache,
    )
    .unwrap();
    let poses = placed_poses(&r.placement);
    assert!(poses.iter().all(Option::is_some), "{:?}", r.placement.maps);
    assert_eq!(r.placement.groups.len(), 2, "{:?}", r.placement.groups);
    for g in &r.placement.groups {
        let office = |m: usize| names[m].split_once("-part-").unwrap().0.to_string();
        assert!(g.iter().all(|&m| office(m) == office(g[0])), "{g:?}");
    }
    let checked = assert_placed_within(&names, &poses, &truths, 1.0, 3.0);
    assert_eq!(checked, 2 * 8 * 7);
    let aligned = r.pairwise.pairs.len();
    assert_eq!(aligned + r.pairwise.screened_out, 120);
    assert!(
        aligned <= 60,
        "{aligned} pairs aligned: {:?}",
        r.pairwise.rounds
    );
    assert_eq!(
        r.pairwise.rounds.iter().map(|x| x.pairs).sum::<usize>(),
        aligned
    );
    // Every pair aligned: the same groups. The maps' preparations and the screened pairs' alignments
    // are kept from the run above (the screen does not change them; a cached run equals a fresh one,
    // as tested above), so only the pairs the screen left are aligned here.
    let all = run_cached(
        &maps,
        &GlobalOptions::with_partners(0),
        &mut ReferenceBackend,
        &|_, _| {},
        &mut cache,
    )
    .unwrap();
    assert_eq!(cache.last_use().pairs_reused, aligned);
    assert_eq!(all.pairwise.pairs.len(), 120);
    assert!(all.pairwise.rounds.is_empty());
    assert_eq!(all.placement.groups, r.placement.groups);
}

/// The real pair set, its 22 maps' names (sorted, then `order`ed) and the maps.
fn real_set(
    dir: &std::path::Path,
    order: impl FnOnce(&mut Vec<String>),
) -> (
    ogm_corners::measure::pairs::PairSet,
    Vec<String>,
    Vec<OccupancyMap>,
) {
    let set = ogm_corners::measure::pairs::PairSet::load(&dir.join("pairs.json")).unwrap();
    let mut names: Vec<String> = set
        .pairs
        .iter()
        .flat_map(|p| [p.src.clone(), p.dst.clone()])
        .collect();
    names.sort();
    names.dedup();
    assert_eq!(names.len(), 22);
    order(&mut names);
    let maps = names
        .iter()
        .map(|n| OccupancyMap::load(dir.join("maps").join(format!("{n}.png"))).unwrap())
        .collect();
    (set, names, maps)
}

/// The real buildings' placement scored against every annotated pair: all 22 maps placed, none wrongly,
/// the three buildings as three groups, and every annotated pair accurate. Returns the row.
fn assert_real_placed_right(
    r: &ogm_corners::measure::merging::many::SetResult,
    set: &ogm_corners::measure::pairs::PairSet,
) -> ogm_corners::measure::merging::many::SetRow {
    let building = |n: &str| n.split('_').next().unwrap().to_string();
    let row = score("real", r, &set.pairs, &building);
    assert_eq!(
        (row.placed, row.wrong, row.groups, row.foreign),
        (22, 0, 3, 0),
        "{row:?}"
    );
    assert_eq!(row.derived_accurate, set.pairs.len(), "{row:?}");
    row
}

/// The 22 real maps of three buildings, screened (22 maps: each aligned first with its 3 most similar):
/// the three buildings whole and apart and every annotated pair accurate through the placement, as when
/// every pair is aligned (docs/merging.md), with under half the pairs.
#[test]
fn the_real_buildings_screened_are_placed_as_with_every_pair() {
    let Some(dir) = common::merge_pairs() else {
        return;
    };
    let (set, names, maps) = real_set(&dir, |_| {});
    let r = run_maps(names.clone(), &maps, &GlobalOptions::default(), &|_, _| {}).unwrap();
    let row = assert_real_placed_right(&r, &set);
    assert!(row.aligned < 231 / 2 + 1, "{} pairs aligned", row.aligned);
}

/// A map added to an earlier merge (`merge --from`): the earlier run's pair alignments, written to its
/// `--poses` document and read back, count as aligned; only pairs with the new map (and the cycles it
/// closes) are aligned, and the result is what carrying the records in memory gives, to the bit, and
/// as good as a full run: every map placed within the synthetic limits, the same groups.
#[test]
fn a_map_added_to_an_earlier_merge_aligns_only_its_pairs_and_places_as_a_full_run() {
    use ogm_corners::measure::merging::many::synthetic_mixed;
    use ogm_corners::merge::many::previous::Previous;
    use ogm_corners::merge::many::{content_id, merge_maps_cached, run, run_cached, Cache};
    let (names, maps, truths) = synthetic_mixed(16, 2, 5).unwrap();
    let options = GlobalOptions::default();
    let old = merge_maps_cached(
        maps[..15].to_vec(),
        &names[..15],
        &options,
        &mut ReferenceBackend,
        &|_, _| {},
        &mut Cache::new(),
    )
    .unwrap();
    let old_pairs = old.run.pairwise.pairs.len();
    assert_eq!(old.report.alignments.len(), old_pairs);
    // Through the file.
    let text = serde_json::to_string_pretty(&old.report).unwrap();
    let previous = Previous::parse(&text, "test").unwrap();
    assert_eq!(previous.maps, names[..15]);
    assert!(previous.fits(&options));
    let mut cache = previous.cache(&options);
    let added = run_cached(
        &maps,
        &options,
        &mut ReferenceBackend,
        &|_, _| {},
        &mut cache,
    )
    .unwrap();
    let used = cache.last_use();
    assert_eq!(used.pairs_reused, old_pairs, "{used:?}");
    assert!(
        used.pairs_aligned >= 1 && used.pairs_aligned < old_pairs,
        "{used:?}"
    );
    // Every old pair is kept; the new ones are the new map's, or cycles it closes.
    assert_eq!(added.pairwise.pairs.len(), old_pairs + used.pairs_aligned);
    assert!(added.pairwise.pairs.iter().any(|p| p.b == 15));
    // The same as carrying the records in memory.
    let mut direct = Cache::new();
    direct.carry(
        old.run
            .records
            .iter()
            .map(|(a, b, r)| (content_id(&maps[*a]), content_id(&maps[*b]), r.clone())),
    );
    let again = run_cached(
        &maps,
        &options,
        &mut ReferenceBackend,
        &|_, _| {},
        &mut direct,
    )
    .unwrap();
    assert_eq!(again.placement, added.placement);
    // As good as a full run.
    let poses = placed_poses(&added.placement);
    assert!(
        poses.iter().all(Option::is_some),
        "{:?}",
        added.placement.maps
    );
    assert_eq!(
        assert_placed_within(&names, &poses, &truths, 1.0, 3.0),
        8 * 7 + 8 * 7
    );
    let full = run(&maps, &options, &mut ReferenceBackend, &|_, _| {}).unwrap();
    assert_eq!(added.placement.groups, full.placement.groups);
    // Other options: the file's alignments are not taken up. Four of the maps show it, at a fraction
    // of the whole set's cost: under the file's options their pairs are taken up.
    let other = GlobalOptions {
        weak_from: options.weak_from + 0.5,
        ..options
    };
    for (opts, fits) in [(options, true), (other, false)] {
        let previous = Previous::parse(&text, "test").unwrap();
        assert_eq!(previous.fits(&opts), fits);
        let mut cache = previous.cache(&opts);
        run_cached(
            &maps[..4],
            &opts,
            &mut ReferenceBackend,
            &|_, _| {},
            &mut cache,
        )
        .unwrap();
        let used = cache.last_use();
        assert_eq!(used.pairs_reused > 0, fits, "{used:?}");
        assert!(fits || used.pairs_aligned > 0, "{used:?}");
    }
}

/// The real buildings, one map added to the other 21's merge: every annotated pair accurate through the
/// placement, the three buildings whole and apart, as in a full run.
#[test]
fn a_real_map_added_to_an_earlier_merge_is_placed_as_in_a_full_run() {
    use ogm_corners::merge::many::{content_id, run_cached, Cache};
    let Some(dir) = common::merge_pairs() else {
        return;
    };
    // KPT4A_04 last: added to the merge of the others.
    let (set, names, maps) = real_set(&dir, |names| {
        let last = names.iter().position(|n| n == "KPT4A_04").unwrap();
        let n = names.remove(last);
        names.push(n);
    });
    let options = GlobalOptions::default();
    let old = run_cached(
        &maps[..21],
        &options,
        &mut ReferenceBackend,
        &|_, _| {},
        &mut Cache::new(),
    )
    .unwrap();
    let mut cache = Cache::new();
    cache.carry(
        old.records
            .iter()
            .map(|(a, b, r)| (content_id(&maps[*a]), content_id(&maps[*b]), r.clone())),
    );
    let added = run_cached(
        &maps,
        &options,
        &mut ReferenceBackend,
        &|_, _| {},
        &mut cache,
    )
    .unwrap();
    assert_eq!(cache.last_use().pairs_reused, old.pairwise.pairs.len());
    assert!(
        cache.last_use().pairs_aligned <= 21,
        "{:?}",
        cache.last_use()
    );
    let r = ogm_corners::measure::merging::many::SetResult::of(names.clone(), added);
    assert_real_placed_right(&r, &set);
}

/// `merge --from FILE NEW...`: the earlier merge's maps read from the paths it recorded, its pairs taken
/// up, the file replaced in place as the new `--poses`; its failures are one-line errors.
#[test]
fn merge_from_an_earlier_poses_file_adds_maps_and_says_what_it_took_up() {
    let d = tempfile::tempdir().unwrap();
    let (names, maps, _) = synthetic_maps(4, 3).unwrap();
    for (n, m) in names.iter().zip(&maps) {
        write_map(d.path(), n, m, 0.05);
    }
    let run = |args: &[&str]| common::tool_in(d.path(), "merge", args);
    let yaml = |k: usize| format!("{}.yaml", names[k]);
    let o = run(&[&yaml(0), &yaml(1), &yaml(2), "--poses", "fleet.json"]);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let first: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.path().join("fleet.json")).unwrap()).unwrap();
    assert_eq!(first["alignments"].as_array().unwrap().len(), 3);
    // The fourth map added, an old one given again (taken once), the file updated in place.
    let o = run(&[
        "--from",
        "fleet.json",
        &yaml(3),
        &yaml(1),
        "--poses",
        "fleet.json",
        "--format",
        "json",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{err}");
    assert!(err.contains("--from: 3 pairs taken up, 3 aligned"), "{err}");
    let out: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(
        out.get("alignments").is_none(),
        "standard output leaves them out"
    );
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.path().join("fleet.json")).unwrap()).unwrap();
    let listed: Vec<&str> = v["maps"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["map"].as_str().unwrap())
        .collect();
    assert_eq!(listed, [yaml(0), yaml(1), yaml(2), yaml(3)]);
    assert!(
        v["maps"]
            .as_array()
            .unwrap()
            .iter()
            .all(|m| m["placed"] == true),
        "{v}"
    );
    assert_eq!(v["alignments"].as_array().unwrap().len(), 6);
    // Taken up again: nothing left to align.
    let o = run(&["--from", "fleet.json"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{err}");
    assert!(err.contains("--from: 6 pairs taken up, 0 aligned"), "{err}");
    // Failures: no file, not a poses document, a map it lists gone.
    for (args, says) in [
        (vec!["--from", "none.json"], "--from none.json: "),
        (vec!["--from", &yaml(0)], "not a `merge --poses` document"),
    ] {
        let o = run(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains(says) && err.lines().count() == 1, "{err}");
    }
    std::fs::remove_file(d.path().join(yaml(2))).unwrap();
    let o = run(&["--from", "fleet.json"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("is not there"), "{err}");
}

/// An engine elsewhere ([`Engine`]), modelled here as a distributed one works: each map's whole
/// preparation kept as bytes and decoded for each pair, the placing side given only the placement form,
/// each pair's record sent as JSON. The run is the local one's, to the bit (screened: signatures too).
#[test]
fn an_engine_moving_bytes_places_as_the_local_threads_to_the_bit() {
    use ogm_corners::measure::merging::many::synthetic_mixed;
    use ogm_corners::merge::many::codec::{self, Form};
    use ogm_corners::merge::many::prescreen::Signature;
    use ogm_corners::merge::many::{run, run_with, Cache, Engine, PairRecord};

    #[derive(Default)]
    struct Bytes {
        whole: std::collections::HashMap<usize, Vec<u8>>,
        aligned: usize,
    }
    impl Engine for Bytes {
        fn prepare(
            &mut self,
            maps: &[(usize, &OccupancyMap)],
            signatures: bool,
        ) -> ogm_corners::Result<Vec<(Prepared, Option<Signature>)>> {
            maps.iter()
                .map(|&(k, m)| {
                    let p = Prepared::new(m);
                    self.whole.insert(k, codec::encode_prepared(&p, Form::Full));
                    let (part, form) =
                        codec::decode_prepared(&codec::encode_prepared(&p, Form::Placement))?;
                    assert_eq!(form, Form::Placement);
                    let s = signatures
                        .then(|| Signature::of(m).map(|s| codec::encode_signature(&s)))
                        .transpose()?;
                    Ok((part, s.map(|s| codec::decode_signature(&s)).transpose()?))
                })
                .collect()
        }
        fn align(
            &mut self,
            _maps: &[Prepared],
            pairs: &[(usize, usize)],
            options: &GlobalOptions,
            _progress: &(dyn Fn(usize, usize) + Sync),
        ) -> ogm_corners::Result<Vec<PairRecord>> {
            self.aligned += pairs.len();
            pairs
                .iter()
                .map(|&(a, b)| {
                    let (pa, _) = codec::decode_prepared(&self.whole[&a])?;
                    let (pb, _) = codec::decode_prepared(&self.whole[&b])?;
                    let al =
                        ogm_corners::merge::pair::align::align_prepared(&pa, &pb, &options.pair)?;
                    PairRecord::from_json(&PairRecord::of(&pa, &pb, &al, options).to_json())
                })
                .collect()
        }
    }
    let (_, maps, _) = synthetic_mixed(14, 2, 9).unwrap();
    let options = GlobalOptions::default();
    let local = run(&maps, &options, &mut ReferenceBackend, &|_, _| {}).unwrap();
    let mut engine = Bytes::default();
    let far = run_with(
        &maps,
        &options,
        &mut ReferenceBackend,
        &|_, _| {},
        &mut Cache::new(),
        &mut engine,
    )
    .unwrap();
    assert!(local.pairwise.screened_out > 0);
    assert_eq!(engine.aligned, local.pairwise.pairs.len());
    assert_eq!(
        serde_json::to_string(&far.pairwise).unwrap(),
        serde_json::to_string(&local.pairwise).unwrap()
    );
    assert_eq!(far.placement, local.placement);
    assert_eq!(far.records, local.records);
}
