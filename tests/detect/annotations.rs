//! `eval --annotations`: recall of hand-marked corners, on a synthetic room and on the shared merge-pairs
//! maps (whose figures this pins, so a change to a detector shows up as a changed table).

use crate::common;
use std::process::Command;

fn eval(args: &[&str]) -> (String, String, Option<i32>) {
    let o = Command::new(env!("CARGO_BIN_EXE_ogm-corners"))
        .arg("eval")
        .args(args)
        .output()
        .unwrap();
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
        o.status.code(),
    )
}

#[test]
fn marked_room_corners_are_found_and_unannotated_maps_are_noted() {
    let d = tempfile::tempdir().unwrap();
    // The room in the top-left corner of a 40 x 40 map that is otherwise unknown, so a mark can lie on
    // the map and far from every corner.
    let art = common::art(&["########", "#......#", "#......#", "#......#", "########"]);
    let mut room =
        ogm_corners::MapImage::filled(40, 40, ogm_corners::map::synthetic::UNKNOWN).unwrap();
    for y in 0..art.height() {
        for x in 0..art.width() {
            room.pixels_mut()[(y * 40 + x) as usize] = art.get(x, y);
        }
    }
    room.write_pgm(&d.path().join("room.pgm")).unwrap();
    room.write_pgm(&d.path().join("other.pgm")).unwrap();
    // The four inner corners are (1,1), (6,1), (1,3), (6,3); one mark is far from all of them.
    let marks = d.path().join("marks.json");
    std::fs::write(
        &marks,
        r#"{"maps": {"room": [[1, 1], [6.4, 1], [1, 3], [30, 30]]}}"#,
    )
    .unwrap();
    let (out, err, code) = eval(&[
        "--backend",
        "cpu",
        "--format",
        "csv",
        "--annotations",
        marks.to_str().unwrap(),
        d.path().to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("no marked points for `other`"), "{err}");
    let ogm = out
        .lines()
        .find(|l| l.starts_with("room,ogm,"))
        .unwrap_or_else(|| panic!("{out}"));
    // marked 4, keypoints 4, three within 5 px and 10 px; the budgets (4, 12) hold every keypoint.
    assert_eq!(ogm, "room,ogm,4,4,3,3,3,3,3,3");
    assert!(
        out.lines().any(|l| l.starts_with("all,ogm,4,4,3,3")),
        "{out}"
    );
    // No map annotated: an error naming the file.
    let (_, err, code) = eval(&[
        "--annotations",
        marks.to_str().unwrap(),
        d.path().join("other.pgm").to_str().unwrap(),
    ]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("none of the maps has marked points"), "{err}");
}

#[test]
fn recall_on_the_shared_annotated_maps() {
    let Some(dir) = common::merge_pairs() else {
        return;
    };
    let (out, err, code) = eval(&[
        "--backend",
        "cpu",
        "--format",
        "csv",
        "--annotations",
        dir.join("corners.json").to_str().unwrap(),
        dir.join("maps").to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{err}");
    let row = |det: &str| {
        out.lines()
            .find(|l| l.starts_with(&format!("all,{det},")))
            .unwrap_or_else(|| panic!("no pooled {det} row in {out}"))
            .to_string()
    };
    // The figures the detector issue measured on these 22 maps (534 marked points): the paper's OGM
    // detector finds 273 keypoints, 31 marked points within 5 px and 55 within 10 px (5.8%, 10.3%);
    // Harris 13971 keypoints, 443 and 512 (83.0%, 95.9%), 98 and 223 with its strongest 3 per mark.
    eprintln!("{out}");
    // The robust detector (docs/detectors.md), by default corners with walls of 12 px or more at scales 2,
    // 3, 4, 6, 8 and 12: 595 keypoints (1.1 per marked point), 285 marked points within 5 px (53.4%) and
    // 370 within 10 px (69.3%); with the strongest as many as the marked points, 276 and 354, where Harris
    // has 40 and 83.
    assert_eq!(
        row("ogm-robust"),
        "all,ogm-robust,534,595,285,370,276,285,354,370"
    );
    assert!(
        row("harris").ends_with(",40,98,83,223"),
        "{}",
        row("harris")
    );
    // Every corner, --min-strength 1: 2920 keypoints; the strongest 3 per marked point have 323 within
    // 5 px (60.5%) and 423 within 10 px (79.2%).
    let (all, err, code) = eval(&[
        "--backend",
        "cpu",
        "--format",
        "csv",
        "--min-strength",
        "1",
        "--annotations",
        dir.join("corners.json").to_str().unwrap(),
        dir.join("maps").to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{err}");
    assert!(
        all.lines()
            .any(|l| l == "all,ogm-robust,534,2920,350,446,278,323,357,423"),
        "{all}"
    );
    assert!(
        row("ogm").starts_with("all,ogm,534,273,31,55,"),
        "{}",
        row("ogm")
    );
    assert!(
        row("harris").starts_with("all,harris,534,13971,443,512,"),
        "{}",
        row("harris")
    );
}
