//! Map loading: formats, yaml fields, classification, world coordinates, and every kind of bad input.

use std::fs;
use std::path::{Path, PathBuf};

use ogm_corners::map::MapYaml;
use ogm_corners::{CellState, ClassTable, Error, GeoRef, MapImage, OccupancyMap, Thresholds};

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("ogm-loading-{}", std::process::id()));
    fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn load_err(path: &Path) -> String {
    match OccupancyMap::load(path) {
        Ok(_) => panic!("{} loaded but should not", path.display()),
        Err(e) => {
            assert_eq!(e.exit_code(), 2, "bad input must be exit status 2: {e}");
            let s = e.to_string();
            assert!(!s.contains('\n'), "one-line error: {s}");
            s
        }
    }
}

const PIXELS: [u8; 6] = [0, 100, 205, 254, 255, 30];

#[test]
fn pgm_p5_and_p2_load_identically() {
    let p5 = tmp("a.pgm");
    let mut bytes = b"P5\n3 2\n255\n".to_vec();
    bytes.extend_from_slice(&PIXELS);
    fs::write(&p5, bytes).unwrap();
    let p2 = tmp("b.pgm");
    fs::write(&p2, "P2\n# a comment\n3 2\n255\n0 100 205\n254 255 30\n").unwrap();
    for p in [&p5, &p2] {
        let m = OccupancyMap::load(p).unwrap();
        assert_eq!((m.image.width(), m.image.height()), (3, 2));
        assert_eq!(m.image.pixels(), &PIXELS);
        assert_eq!(m.thresholds, Thresholds::default());
        assert!(m.georef.is_none());
    }
}

#[test]
fn pgm_16_bit_is_scaled_to_8_bit() {
    let p = tmp("c16.pgm");
    let mut bytes = b"P5\n3 1\n65535\n".to_vec();
    for v in [0u16, 65535, 205 * 257] {
        bytes.extend_from_slice(&v.to_be_bytes());
    }
    fs::write(&p, bytes).unwrap();
    let m = OccupancyMap::load(&p).unwrap();
    assert_eq!(m.image.pixels(), &[0, 255, 205]);
}

#[test]
fn png_grey_alpha_rgb_rgba_load_as_grey() {
    let grey = image::GrayImage::from_raw(3, 2, PIXELS.to_vec()).unwrap();
    let cases: Vec<(&str, image::DynamicImage)> = vec![
        ("g.png", image::DynamicImage::ImageLuma8(grey.clone())),
        (
            "ga.png",
            image::DynamicImage::ImageLumaA8(
                image::DynamicImage::ImageLuma8(grey.clone()).to_luma_alpha8(),
            ),
        ),
        (
            "rgb.png",
            image::DynamicImage::ImageRgb8(image::DynamicImage::ImageLuma8(grey.clone()).to_rgb8()),
        ),
        (
            "rgba.png",
            image::DynamicImage::ImageRgba8(
                image::DynamicImage::ImageLuma8(grey.clone()).to_rgba8(),
            ),
        ),
    ];
    for (name, img) in cases {
        let p = tmp(name);
        img.save(&p).unwrap();
        let m = OccupancyMap::load(&p).unwrap();
        assert_eq!(m.image.pixels(), &PIXELS, "{name}");
    }
    // Colour goes by luminance: pure green is brighter than pure blue.
    let p = tmp("colour.png");
    image::RgbImage::from_raw(2, 1, vec![0, 255, 0, 0, 0, 255])
        .unwrap()
        .save(&p)
        .unwrap();
    let px = OccupancyMap::load(&p).unwrap().image.pixels().to_vec();
    assert!(px[0] > 150 && px[1] < 40, "{px:?}");
}

#[test]
fn yaml_loads_its_image_relative_to_itself() {
    let dir = tmp("yamldir");
    fs::create_dir_all(dir.join("sub")).unwrap();
    let mut bytes = b"P5\n3 2\n255\n".to_vec();
    bytes.extend_from_slice(&PIXELS);
    fs::write(dir.join("sub/m.pgm"), bytes).unwrap();
    fs::write(
        dir.join("m.yaml"),
        "image: sub/m.pgm\nresolution: 0.05\norigin: [-1.5, 2.0, 0.0]\nnegate: 1\noccupied_thresh: 0.7\nfree_thresh: 0.2\nmode: trinary\n",
    )
    .unwrap();
    let m = OccupancyMap::load(dir.join("m.yaml")).unwrap();
    assert_eq!(m.image.pixels(), &PIXELS);
    assert_eq!(
        m.thresholds,
        Thresholds {
            negate: true,
            occupied_thresh: 0.7,
            free_thresh: 0.2
        }
    );
    assert_eq!(
        m.georef,
        Some(GeoRef {
            resolution: 0.05,
            origin: [-1.5, 2.0, 0.0]
        })
    );
    assert!(m.warnings.is_empty());
}

#[test]
fn yaml_defaults_and_nan_yaw() {
    let y = MapYaml::parse("image: m.pgm\nresolution: 0.1\norigin: [0, 0, nan]\n").unwrap();
    assert_eq!(y.thresholds, Thresholds::default());
    assert!(y.origin[2].is_nan());
    let g = GeoRef {
        resolution: 0.1,
        origin: y.origin,
    };
    assert_eq!(g.pixel_to_world(0, 9, 10), (0.05, 0.05));
}

#[test]
fn classification_follows_ros_trinary_semantics() {
    let t = ClassTable::default();
    assert_eq!(t.state(0), CellState::Occupied);
    assert_eq!(t.state(205), CellState::Unknown);
    assert_eq!(t.state(254), CellState::Free);
    assert_eq!(t.state(255), CellState::Free);
    // The boundaries: p > 0.65 occupied, i.e. v < 89.25; p < 0.196, i.e. v > 205.02.
    assert_eq!(t.state(89), CellState::Occupied);
    assert_eq!(t.state(90), CellState::Unknown);
    assert_eq!(t.state(205), CellState::Unknown);
    assert_eq!(t.state(206), CellState::Free);
    let neg = ClassTable::new(&Thresholds {
        negate: true,
        ..Thresholds::default()
    });
    assert_eq!(neg.state(255), CellState::Occupied);
    assert_eq!(neg.state(0), CellState::Free);
    assert_eq!(neg.state(50), CellState::Unknown);
}

#[test]
fn world_coordinates_follow_ros_convention() {
    // The origin is the lower-left pixel's corner; row 0 is the top of the image.
    let g = GeoRef {
        resolution: 0.5,
        origin: [10.0, 20.0, 0.0],
    };
    assert_eq!(g.pixel_to_world(0, 3, 4), (10.25, 20.25));
    assert_eq!(g.pixel_to_world(2, 0, 4), (11.25, 21.75));
    // A quarter turn of yaw turns the map about the origin: +x in the map becomes +y in the world.
    let g = GeoRef {
        resolution: 1.0,
        origin: [0.0, 0.0, std::f64::consts::FRAC_PI_2],
    };
    let (x, y) = g.pixel_to_world(1, 0, 1);
    assert!(
        (x + 0.5).abs() < 1e-12 && (y - 1.5).abs() < 1e-12,
        "{x} {y}"
    );
}

#[test]
fn bad_yaml_gives_clear_errors() {
    let cases = [
        ("broken.yaml", "image: [unclosed\n", "broken yaml"),
        ("empty.yaml", "", "empty yaml"),
        (
            "noimage.yaml",
            "resolution: 0.05\norigin: [0, 0, 0]\n",
            "missing `image`",
        ),
        (
            "nores.yaml",
            "image: m.pgm\norigin: [0, 0, 0]\n",
            "missing `resolution`",
        ),
        (
            "noorigin.yaml",
            "image: m.pgm\nresolution: 0.05\n",
            "missing `origin`",
        ),
        (
            "badres.yaml",
            "image: m.pgm\nresolution: -1\norigin: [0, 0, 0]\n",
            "resolution",
        ),
        (
            "badorigin.yaml",
            "image: m.pgm\nresolution: 0.05\norigin: 3\n",
            "origin",
        ),
        (
            "raw.yaml",
            "image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nmode: raw\n",
            "unsupported mode `raw`",
        ),
        (
            "thresh.yaml",
            "image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nfree_thresh: 0.9\n",
            "free_thresh",
        ),
        (
            "negate.yaml",
            "image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 3\n",
            "negate",
        ),
        ("list.yaml", "- a\n- b\n", "not a mapping"),
        (
            "noimg.yaml",
            "image: nowhere.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n",
            "nowhere.pgm: cannot read",
        ),
    ];
    for (name, text, want) in cases {
        let p = tmp(name);
        fs::write(&p, text).unwrap();
        let e = load_err(&p);
        assert!(e.contains(want), "{name}: {e}");
        if want != "nowhere.pgm: cannot read" {
            assert!(e.contains(name), "{name}: error must name the file: {e}");
        }
    }
}

#[test]
fn bad_images_give_clear_errors() {
    let p = tmp("truncated.pgm");
    fs::write(&p, b"P5\n100 100\n255\n\x00\x01").unwrap();
    assert!(load_err(&p).contains("truncated"));

    let mut png = Vec::new();
    image::GrayImage::new(64, 64)
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    let p = tmp("truncated.png");
    fs::write(&p, &png[..png.len() / 2]).unwrap();
    assert!(load_err(&p).contains("cannot decode PNG"));

    let p = tmp("unknown.bin");
    fs::write(&p, b"this is not an image at all").unwrap();
    assert!(load_err(&p).contains("unknown image format"));

    let p = tmp("empty.pgm");
    fs::write(&p, b"").unwrap();
    assert!(load_err(&p).contains("empty file"));

    let p = tmp("zero.pgm");
    fs::write(&p, b"P5\n0 0\n255\n").unwrap();
    let e = load_err(&p);
    assert!(e.contains("zero.pgm"), "{e}");

    let p = tmp("huge.pgm");
    fs::write(&p, b"P5\n1000000 1000000\n255\n\x00").unwrap();
    load_err(&p);

    let e = load_err(Path::new("/nonexistent/map.pgm"));
    assert!(
        e.contains("/nonexistent/map.pgm") && e.contains("cannot read"),
        "{e}"
    );
}

#[test]
fn zero_size_and_mismatched_maps_in_memory_are_errors() {
    assert!(matches!(
        MapImage::new(0, 5, vec![]),
        Err(Error::Input { .. })
    ));
    assert!(matches!(
        MapImage::new(3, 3, vec![0; 8]),
        Err(Error::Input { .. })
    ));
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(400))]

    /// Any text: the map yaml parser returns a map or a one-line message, never panics.
    #[test]
    fn any_yaml_text_parses_or_fails_cleanly(text in ".{0,300}") {
        if let Err(e) = ogm_corners::map::MapYaml::parse(&text) {
            proptest::prop_assert!(!e.contains('\n'));
        }
    }

    /// Any file contents, named .yaml, .pgm or .png: loading gives a map or a one-line error naming the
    /// file, never a panic.
    #[test]
    fn any_file_loads_or_fails_cleanly(
        bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..400),
        prefix in proptest::sample::select(vec![&b""[..], b"P5\n3 2\n255\n", b"P2\n", b"\x89PNG\r\n\x1a\n", b"image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n"]),
        ext in proptest::sample::select(vec!["yaml", "pgm", "png"]),
    ) {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join(format!("m.{ext}"));
        let mut data = prefix.to_vec();
        data.extend(&bytes);
        std::fs::write(&p, &data).unwrap();
        // A yaml's image: the same bytes again.
        std::fs::write(dir.path().join("m.pgm"), &data).unwrap();
        match ogm_corners::OccupancyMap::load(&p) {
            Ok(m) => proptest::prop_assert_eq!(m.image.len() as u64, u64::from(m.image.width()) * u64::from(m.image.height())),
            Err(e) => {
                let m = e.to_string();
                proptest::prop_assert!(!m.contains('\n'), "{}", m);
                proptest::prop_assert_eq!(e.exit_code(), 2);
            }
        }
    }
}
