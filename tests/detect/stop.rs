//! Long work stops at its next check once its [`Stop`] is raised (what Ctrl-C does in Python), and runs to
//! its end under no stop or an unraised one.

use std::sync::atomic::{AtomicUsize, Ordering};

use ogm_corners::backend::reference::ReferenceBackend;
use ogm_corners::detect::detector::{DetectOptions, DetectorKind};
use ogm_corners::map::synthetic::office_map;
use ogm_corners::measure::merging::many::synthetic_maps;
use ogm_corners::merge::many::mosaic;
use ogm_corners::merge::many::{merge_maps, GlobalOptions};
use ogm_corners::support::stop::Stop;
use ogm_corners::{Detector, Error, OccupancyMap};

#[test]
fn a_raised_stop_ends_the_robust_detector_and_an_unraised_one_changes_nothing() {
    let map = OccupancyMap::from_image(office_map(600, 400, 3).unwrap());
    let mut d = Detector::new(DetectOptions {
        detector: DetectorKind::OgmRobust,
        ..Default::default()
    });
    let plain = d.detect(&map).unwrap();
    let stop = Stop::new();
    let under = stop.run(|| d.detect(&map)).unwrap();
    assert_eq!(under.keypoints, plain.keypoints);
    stop.raise();
    assert!(matches!(
        stop.run(|| d.detect(&map)),
        Err(Error::Interrupted)
    ));
    // The detector is whole afterwards.
    assert_eq!(d.detect(&map).unwrap().keypoints, plain.keypoints);
}

#[test]
fn a_stop_raised_midway_ends_a_many_map_merge_before_its_remaining_pairs() {
    let (names, maps, _) = synthetic_maps(8, 4).unwrap();
    let pairs_done = AtomicUsize::new(0);
    let stop = Stop::new();
    let r = stop.run(|| {
        merge_maps(
            maps.clone(),
            &names,
            &GlobalOptions::default(),
            &mut ReferenceBackend,
            &|k, _| {
                pairs_done.fetch_add(1, Ordering::Relaxed);
                if k >= 3 {
                    stop.raise();
                }
            },
        )
    });
    assert!(matches!(r, Err(Error::Interrupted)), "{:?}", r.err());
    // 28 pairs; those already running when it was raised finish, the others are skipped.
    let done = pairs_done.load(Ordering::Relaxed);
    assert!(done < 28, "{done} pairs aligned after the stop");
    assert_eq!(Error::Interrupted.exit_code(), 130);

    // Unraised, the same merge runs to its end; drawing it stops map by map.
    let merged = Stop::new()
        .run(|| {
            merge_maps(
                maps,
                &names,
                &GlobalOptions::default(),
                &mut ReferenceBackend,
                &|_, _| {},
            )
        })
        .unwrap();
    assert!(merged.merged(0).is_ok());
    let raised = Stop::new();
    raised.raise();
    let refs: Vec<&OccupancyMap> = merged.maps.iter().collect();
    let poses = vec![ogm_corners::merge::Rigid::IDENTITY; refs.len()];
    assert!(matches!(
        raised.run(|| mosaic::compose_many(&refs, &poses)),
        Err(Error::Interrupted)
    ));
}
