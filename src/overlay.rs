//! A PNG of the map with each keypoint marked in colour, for a person to look at.

use std::path::Path;

use image::{Rgb, RgbImage};

use crate::detector::Keypoint;
use crate::error::{Error, Result};
use crate::map::MapImage;

/// Marker colour of each rule: 4 orange, 5 red, 6 blue.
pub fn rule_colour(rule: u8) -> Rgb<u8> {
    match rule {
        4 => Rgb([255, 140, 0]),
        5 => Rgb([230, 0, 0]),
        6 => Rgb([0, 90, 255]),
        _ => Rgb([200, 0, 200]),
    }
}

/// The integer zoom used for a map: small maps are enlarged so a marker is visible, large ones are not.
pub fn overlay_scale(width: u32, height: u32) -> u32 {
    (1200 / width.max(height)).clamp(1, 8)
}

/// Draws the map (grey levels as they are) enlarged by [`overlay_scale`], each keypoint's cell filled with
/// its rule's colour and circled so that it stands out at any zoom.
pub fn render_overlay(map: &MapImage, keypoints: &[Keypoint]) -> RgbImage {
    let s = overlay_scale(map.width(), map.height());
    let (w, h) = (map.width() * s, map.height() * s);
    let mut img = RgbImage::from_fn(w, h, |x, y| {
        let v = map.get(x / s, y / s);
        Rgb([v, v, v])
    });
    let radius = (2 * s + 2) as i64;
    for k in keypoints {
        let colour = rule_colour(k.rule);
        for dy in 0..s {
            for dx in 0..s {
                img.put_pixel(k.x * s + dx, k.y * s + dy, colour);
            }
        }
        // Centre of the enlarged cell, in doubled coordinates so that even zooms stay symmetric.
        let cx2 = (2 * k.x * s + s) as i64;
        let cy2 = (2 * k.y * s + s) as i64;
        ring(&mut img, cx2, cy2, radius, colour);
    }
    img
}

/// A one-pixel-wide circle of `radius` around the doubled-coordinate centre (cx2 / 2, cy2 / 2).
fn ring(img: &mut RgbImage, cx2: i64, cy2: i64, radius: i64, colour: Rgb<u8>) {
    let (w, h) = (img.width() as i64, img.height() as i64);
    let (r_in, r_out) = (2 * radius - 1, 2 * radius + 1);
    let x0 = (cx2 / 2 - radius - 1).max(0);
    let y0 = (cy2 / 2 - radius - 1).max(0);
    for y in y0..(cy2 / 2 + radius + 2).min(h) {
        for x in x0..(cx2 / 2 + radius + 2).min(w) {
            let (dx, dy) = (2 * x + 1 - cx2, 2 * y + 1 - cy2);
            let d2 = dx * dx + dy * dy;
            if d2 >= r_in * r_in && d2 <= r_out * r_out {
                img.put_pixel(x as u32, y as u32, colour);
            }
        }
    }
}

/// Renders and writes the overlay as a PNG.
pub fn write_overlay(path: &Path, map: &MapImage, keypoints: &[Keypoint]) -> Result<()> {
    render_overlay(map, keypoints)
        .save_with_format(path, image::ImageFormat::Png)
        .map_err(|e| Error::output(path, e))
}
