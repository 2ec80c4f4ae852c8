//! A PNG of the map with each keypoint marked in colour, for a person to look at.

use std::path::Path;

use image::{Rgb, RgbImage};

use crate::backend::Keypoint;
use crate::error::Result;
use crate::map::MapImage;

/// Marker colour of each rule: 4 orange, 5 red, 6 blue; the baselines' keypoints (rule 0) magenta.
pub fn rule_colour(rule: u8) -> Rgb<u8> {
    match rule {
        4 => Rgb([255, 140, 0]),
        5 => Rgb([230, 0, 0]),
        6 => Rgb([0, 90, 255]),
        _ => Rgb([200, 0, 200]),
    }
}

/// Longest side of an overlay of a large map; larger maps are shrunk to it, so that an overlay of a huge
/// map stays a viewable PNG of bounded memory.
pub const MAX_OVERLAY_SIDE: u32 = 8192;

/// The integer zoom used for a map: small maps are enlarged so a marker is visible, large ones are not.
pub fn overlay_scale(width: u32, height: u32) -> u32 {
    (1200 / width.max(height)).clamp(1, 8)
}

/// The integer shrink factor for maps over [`MAX_OVERLAY_SIDE`] (1 otherwise).
pub fn overlay_shrink(width: u32, height: u32) -> u32 {
    width.max(height).div_ceil(MAX_OVERLAY_SIDE)
}

/// Draws the map (grey levels as they are) enlarged by [`overlay_scale`] (or, for maps over
/// [`MAX_OVERLAY_SIDE`], shrunk by [`overlay_shrink`], each output pixel the darkest of its block so walls
/// stay visible), each keypoint's cell filled with its rule's colour and circled so that it stands out at
/// any zoom.
pub fn render_overlay(map: &MapImage, keypoints: &[Keypoint]) -> RgbImage {
    let s = overlay_scale(map.width(), map.height());
    let d = overlay_shrink(map.width(), map.height());
    render_overlay_at(map, keypoints, s, d)
}

/// [`render_overlay`] with an explicit zoom `s` (>= 1) or shrink `d` (>= 1).
pub fn render_overlay_at(map: &MapImage, keypoints: &[Keypoint], s: u32, d: u32) -> RgbImage {
    let (s, d) = (s.max(1), d.max(1));
    let (w, h) = (map.width().div_ceil(d) * s, map.height().div_ceil(d) * s);
    let mut img = RgbImage::from_fn(w, h, |x, y| {
        let (bx, by) = ((x / s) * d, (y / s) * d);
        let mut v = u8::MAX;
        for yy in by..(by + d).min(map.height()) {
            for xx in bx..(bx + d).min(map.width()) {
                v = v.min(map.get(xx, yy));
            }
        }
        Rgb([v, v, v])
    });
    let radius = (2 * s + 2) as i64;
    for k in keypoints {
        let colour = rule_colour(k.rule);
        let (kx, ky) = (k.x / d, k.y / d);
        for dy in 0..s {
            for dx in 0..s {
                img.put_pixel(kx * s + dx, ky * s + dy, colour);
            }
        }
        // Centre of the enlarged cell, in doubled coordinates so that even zooms stay symmetric.
        let cx2 = (2 * kx * s + s) as i64;
        let cy2 = (2 * ky * s + s) as i64;
        ring(&mut img, cx2, cy2, radius, colour);
    }
    img
}

/// A one-pixel-wide circle of `radius` around the doubled-coordinate centre (cx2 / 2, cy2 / 2).
pub fn ring(img: &mut RgbImage, cx2: i64, cy2: i64, radius: i64, colour: Rgb<u8>) {
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

/// Bytes [`render_overlay`] and its PNG encoding allocate for a `width` x `height` map (the RGB picture,
/// and at most as much again for the compressed stream the encoder keeps), for memory budgets.
pub fn overlay_bytes(width: u32, height: u32) -> u64 {
    let (s, d) = (
        u64::from(overlay_scale(width, height)),
        u64::from(overlay_shrink(width, height)),
    );
    let side = |n: u32| u64::from(n).div_ceil(d) * s;
    6 * side(width) * side(height)
}

/// Renders and writes the overlay as a PNG, atomically ([`crate::files::write_atomic`]).
pub fn write_overlay(path: &Path, map: &MapImage, keypoints: &[Keypoint]) -> Result<()> {
    crate::files::write_png(path, &render_overlay(map, keypoints))
}
