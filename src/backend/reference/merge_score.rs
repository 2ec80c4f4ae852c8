//! CPU twin of the transform-scoring kernel (`shaders/merge_score.wgsl`): the map merger's candidate rigid
//! transforms scored by mapping one map's wall pixels into the other map and counting how many land on
//! pixels with each flag.
//!
//! Everything is exact integer arithmetic: a transform is fixed point with [`SCORE_FRAC_BITS`] fraction
//! bits, a point lands on pixel `((cos x - sin y + tx + h) >> F, (sin x + cos y + ty + h) >> F)` with
//! `h = 2^(F-1)` (nearest pixel, halves rounded up), and every intermediate fits an `i32` (WGSL has no
//! 64-bit integers by default): with `|cos|, |sin| <= 2^13`, coordinates below 2^15 and translations
//! within 2^30, `|cos x| + |sin y| < 2^13 * 2^15 * sqrt(2) + 2^16 < 2^29` (the rounded cosine and sine
//! exceed the unit circle by at most half a unit each), so the sum stays below `2^29 + 2^30 + 2^12 < 2^31`.

use rayon::prelude::*;

use crate::support::error::{Error, Result};

/// Fraction bits of the fixed-point transforms.
pub const SCORE_FRAC_BITS: u32 = 13;

/// Largest target side and largest point coordinate (exclusive), pixels: keeps every product in i32.
pub const MAX_SCORE_SIDE: u32 = 1 << 15;

/// Flag bit of a target pixel: the pixel is known, or within 5 px of a wall.
pub const FLAG_INSIDE: u8 = 1;
/// Flag bit of a target pixel: within 5 px of a wall.
pub const FLAG_NEAR: u8 = 2;
/// Flag bit of a target pixel: more than 20 px deep inside free space.
pub const FLAG_DEEP: u8 = 4;

/// Largest translation [`FixedRigid::new`] keeps, pixels: beyond it nothing of a map of side below
/// [`MAX_SCORE_SIDE`] lands on the target, and `2^17 * 2^13 = 2^30` keeps the sums in `i32`.
const MAX_TRANSLATION_PX: f64 = (1u32 << 17) as f64;

/// `1.0` in fixed point: the largest magnitude of a transform's cosine and sine.
const ONE: i32 = 1 << SCORE_FRAC_BITS;

/// The largest magnitude of a transform's fixed-point translation (`2^17` px).
const MAX_T: i32 = 1 << (17 + SCORE_FRAC_BITS);

/// A target map of flag bytes ([`FLAG_INSIDE`], [`FLAG_NEAR`], [`FLAG_DEEP`]), row-major.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ScoreTarget {
    /// Pixels a row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// `width * height` flag bytes, row-major; bits other than the three flags are ignored.
    pub flags: Vec<u8>,
}

impl ScoreTarget {
    /// A target of `width` x `height` flag bytes: both sides in `1..=MAX_SCORE_SIDE` and exactly
    /// `width * height` bytes.
    pub fn new(width: u32, height: u32, flags: Vec<u8>) -> Result<Self> {
        let t = ScoreTarget {
            width,
            height,
            flags,
        };
        t.check()?;
        Ok(t)
    }

    /// Checks the invariants [`ScoreTarget::new`] establishes (the fields are public, so they are checked
    /// again before scoring).
    pub fn check(&self) -> Result<()> {
        let (w, h) = (self.width, self.height);
        if w == 0 || h == 0 || w > MAX_SCORE_SIDE || h > MAX_SCORE_SIDE {
            return Err(Error::invalid(format!(
                "score target is {w}x{h}: each side must be 1 to {MAX_SCORE_SIDE} pixels"
            )));
        }
        let want = w as usize * h as usize;
        if self.flags.len() != want {
            return Err(Error::invalid(format!(
                "score target is {w}x{h} but has {} flag bytes, not {want}",
                self.flags.len()
            )));
        }
        Ok(())
    }

    /// The flags of the pixel a point lands on; `None` outside the target.
    #[inline]
    pub fn flags_at(&self, x: i32, y: i32) -> Option<u8> {
        if x < 0 || y < 0 || x as u32 >= self.width || y as u32 >= self.height {
            return None;
        }
        Some(self.flags[y as usize * self.width as usize + x as usize])
    }
}

/// A rigid transform in fixed point: q = R p + t with cos, sin, tx, ty scaled by 2^SCORE_FRAC_BITS.
///
/// Laid out as the kernel's `vec4<i32>` transforms (cos, sin, tx, ty).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct FixedRigid {
    /// cos(angle), fixed point: at most `2^13` in magnitude.
    pub cos: i32,
    /// sin(angle), fixed point: at most `2^13` in magnitude.
    pub sin: i32,
    /// Translation along x, fixed point: at most `2^30` (2^17 px) in magnitude.
    pub tx: i32,
    /// Translation along y, fixed point: at most `2^30` (2^17 px) in magnitude.
    pub ty: i32,
}

impl FixedRigid {
    /// From degrees and pixels (each value rounded to the nearest 1/2^13); translations beyond
    /// +-2^17 px are clamped to +-2^17 (nothing of a map of side < 2^15 can land anywhere then, and i32
    /// holds every sum). A NaN becomes 0 (a NaN or infinite angle gives cos = sin = 0, every point landing
    /// on the translation), so this never fails.
    pub fn new(theta_deg: f64, tx: f64, ty: f64) -> FixedRigid {
        let (s, c) = theta_deg.to_radians().sin_cos();
        // `as` saturates and maps NaN to 0; the clamps keep every value within the bounds above.
        let fixed = |v: f64| (v * f64::from(ONE)).round() as i32;
        let t = |v: f64| fixed(v.clamp(-MAX_TRANSLATION_PX, MAX_TRANSLATION_PX));
        FixedRigid {
            cos: fixed(c).clamp(-ONE, ONE),
            sin: fixed(s).clamp(-ONE, ONE),
            tx: t(tx),
            ty: t(ty),
        }
    }

    /// The identity transform.
    pub const IDENTITY: FixedRigid = FixedRigid {
        cos: ONE,
        sin: 0,
        tx: 0,
        ty: 0,
    };

    /// Where the point lands: ((cos*x - sin*y + tx + half) >> F, (sin*x + cos*y + ty + half) >> F),
    /// arithmetic shift (floor), half = 1 << (F-1). Wrapping arithmetic, as WGSL's i32: within the bounds
    /// [`score_transforms`] checks nothing wraps, and outside them this still never panics.
    #[inline]
    pub fn apply(&self, x: i32, y: i32) -> (i32, i32) {
        let half = 1i32 << (SCORE_FRAC_BITS - 1);
        let qx = self
            .cos
            .wrapping_mul(x)
            .wrapping_sub(self.sin.wrapping_mul(y))
            .wrapping_add(self.tx)
            .wrapping_add(half);
        let qy = self
            .sin
            .wrapping_mul(x)
            .wrapping_add(self.cos.wrapping_mul(y))
            .wrapping_add(self.ty)
            .wrapping_add(half);
        (qx >> SCORE_FRAC_BITS, qy >> SCORE_FRAC_BITS)
    }
}

/// Checks everything [`score_transforms`] needs of its input, so that every backend refuses the same
/// input with the same message: the target's invariants, point coordinates below [`MAX_SCORE_SIDE`], a
/// point count that fits the `u32` counts, and transforms within the bounds that keep the sums in `i32`.
pub fn check_score_input(
    target: &ScoreTarget,
    points: &[[u32; 2]],
    transforms: &[FixedRigid],
) -> Result<()> {
    target.check()?;
    if u32::try_from(points.len()).is_err() {
        return Err(Error::invalid(format!(
            "{} points to score: at most {} (the counts are u32)",
            points.len(),
            u32::MAX
        )));
    }
    if let Some((i, p)) = points
        .iter()
        .enumerate()
        .find(|(_, p)| p[0] >= MAX_SCORE_SIDE || p[1] >= MAX_SCORE_SIDE)
    {
        return Err(Error::invalid(format!(
            "point {i} is ({}, {}): coordinates must be below {MAX_SCORE_SIDE}",
            p[0], p[1]
        )));
    }
    if let Some((i, t)) = transforms.iter().enumerate().find(|(_, t)| {
        t.cos.unsigned_abs() > ONE as u32
            || t.sin.unsigned_abs() > ONE as u32
            || t.tx.unsigned_abs() > MAX_T as u32
            || t.ty.unsigned_abs() > MAX_T as u32
    }) {
        return Err(Error::invalid(format!(
            "transform {i} is {t:?}: cos and sin must be within +-{ONE} and tx, ty within +-{MAX_T} \
             (use FixedRigid::new)"
        )));
    }
    Ok(())
}

/// The counts of one transform: points landing on a pixel with [`FLAG_INSIDE`], [`FLAG_NEAR`] and
/// [`FLAG_DEEP`].
fn score_one(target: &ScoreTarget, points: &[[u32; 2]], t: &FixedRigid) -> [u32; 3] {
    let mut counts = [0u32; 3];
    for p in points {
        let (x, y) = t.apply(p[0] as i32, p[1] as i32);
        if let Some(f) = target.flags_at(x, y) {
            counts[0] += u32::from(f & FLAG_INSIDE != 0);
            counts[1] += u32::from(f & FLAG_NEAR != 0);
            counts[2] += u32::from(f & FLAG_DEEP != 0);
        }
    }
    counts
}

/// Per transform, how many of `points` land on a target pixel with FLAG_INSIDE, FLAG_NEAR and FLAG_DEEP
/// set (points landing outside the target count nowhere). Points are (x, y), each below
/// [`MAX_SCORE_SIDE`]; transforms must be within the bounds [`FixedRigid::new`] keeps.
pub fn score_transforms(
    target: &ScoreTarget,
    points: &[[u32; 2]],
    transforms: &[FixedRigid],
) -> Result<Vec<[u32; 3]>> {
    check_score_input(target, points, transforms)?;
    // One transform per task: the counts do not depend on the order, so all cores give the same result.
    Ok(transforms
        .par_iter()
        .map(|t| score_one(target, points, t))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::synthetic::Rng;

    #[test]
    fn the_zero_transform_maps_every_point_to_itself() {
        let t = FixedRigid::new(0.0, 0.0, 0.0);
        assert_eq!(t, FixedRigid::IDENTITY);
        for (x, y) in [(0, 0), (1, 0), (0, 1), (12345, 32767), (32767, 32767)] {
            assert_eq!(t.apply(x, y), (x, y));
        }
    }

    #[test]
    fn a_quarter_turn_maps_x_y_to_minus_y_x() {
        let t = FixedRigid::new(90.0, 0.0, 0.0);
        assert_eq!((t.cos, t.sin), (0, ONE));
        for (x, y) in [(0, 0), (1, 0), (0, 1), (7, 3), (32767, 12)] {
            assert_eq!(t.apply(x, y), (-y, x));
        }
        let t = FixedRigid::new(-90.0, 5.0, -2.0);
        assert_eq!(t.apply(7, 3), (3 + 5, -7 - 2));
    }

    #[test]
    fn rounding_and_clamping_of_the_fixed_point_values() {
        let t = FixedRigid::new(180.0, 0.5 / 8192.0, -1e9);
        assert_eq!((t.cos, t.sin), (-ONE, 0));
        assert_eq!(t.tx, 1); // half a unit rounds away from zero
        assert_eq!(t.ty, -MAX_T);
        assert_eq!(FixedRigid::new(0.0, f64::INFINITY, 1e300).tx, MAX_T);
        let nan = FixedRigid::new(f64::NAN, f64::NAN, 3.0);
        assert_eq!(nan, FixedRigid::new(f64::NAN, 0.0, 3.0));
        assert_eq!((nan.cos, nan.sin, nan.tx), (0, 0, 0));
        // Landing halves round up: 0.5 px lands on pixel 1, -0.5 px on pixel 0.
        let half = FixedRigid::new(0.0, 0.5, -0.5);
        assert_eq!(half.apply(0, 0), (1, 0));
    }

    #[test]
    fn the_extreme_transforms_stay_in_i32() {
        // Largest coordinates, largest translations and the diagonal where |cos| + |sin| peaks: the
        // exact 64-bit result equals the i32 one.
        let m = (MAX_SCORE_SIDE - 1) as i32;
        for deg in [45.0, 135.0, -45.0, -135.0, 44.99, 0.0, 90.0] {
            for (tx, ty) in [(1e9, 1e9), (-1e9, -1e9), (1e9, -1e9)] {
                let t = FixedRigid::new(deg, tx, ty);
                for (x, y) in [(m, m), (m, 0), (0, m), (0, 0)] {
                    let wide = |a: i32, b: i32, c: i32| {
                        let v = i64::from(a) * i64::from(x)
                            + i64::from(b) * i64::from(y)
                            + i64::from(c)
                            + 4096;
                        assert!(v.abs() < 1 << 31, "{deg} {tx} {ty}");
                        (v >> SCORE_FRAC_BITS) as i32
                    };
                    let want = (wide(t.cos, -t.sin, t.tx), wide(t.sin, t.cos, t.ty));
                    assert_eq!(t.apply(x, y), want);
                }
            }
        }
    }

    #[test]
    fn counts_equal_a_floating_point_reference() {
        let mut rng = Rng::new(3);
        let (w, h) = (37u32, 23u32);
        let flags: Vec<u8> = (0..w * h).map(|_| rng.range(0, 8) as u8).collect();
        let target = ScoreTarget::new(w, h, flags.clone()).unwrap();
        let points: Vec<[u32; 2]> = (0..300)
            .map(|_| [rng.range(0, 60), rng.range(0, 40)])
            .collect();
        let mut transforms = vec![FixedRigid::IDENTITY];
        for _ in 0..40 {
            let deg = f64::from(rng.range(0, 3600)) / 10.0 - 180.0;
            let tx = f64::from(rng.range(0, 8000)) / 100.0 - 40.0;
            let ty = f64::from(rng.range(0, 8000)) / 100.0 - 40.0;
            transforms.push(FixedRigid::new(deg, tx, ty));
        }
        let got = score_transforms(&target, &points, &transforms).unwrap();
        let mut compared = 0;
        for (t, counts) in transforms.iter().zip(&got) {
            // The float transform of the fixed-point values, rounded half up; a landing too close to a
            // half (where f64 rounding could differ) skips the transform.
            let f = |v: i32| f64::from(v) / f64::from(ONE);
            let mut want = [0u32; 3];
            let mut near_half = false;
            for p in &points {
                let (x, y) = (f64::from(p[0]), f64::from(p[1]));
                let qx = f(t.cos) * x - f(t.sin) * y + f(t.tx);
                let qy = f(t.sin) * x + f(t.cos) * y + f(t.ty);
                for q in [qx, qy] {
                    near_half |= ((q - q.floor()) - 0.5).abs() < 1e-9;
                }
                let (ix, iy) = ((qx + 0.5).floor(), (qy + 0.5).floor());
                if ix >= 0.0 && iy >= 0.0 && ix < f64::from(w) && iy < f64::from(h) {
                    let fl = flags[iy as usize * w as usize + ix as usize];
                    for (k, bit) in [FLAG_INSIDE, FLAG_NEAR, FLAG_DEEP].into_iter().enumerate() {
                        want[k] += u32::from(fl & bit != 0);
                    }
                }
            }
            if !near_half {
                assert_eq!(*counts, want, "{t:?}");
                compared += 1;
            }
        }
        assert!(compared > 30, "{compared}");
        // The identity lands every point inside the target on its own pixel.
        let inside = points.iter().filter(|p| p[0] < w && p[1] < h).count() as u32;
        assert!(got[0][0] <= inside && got[0][0] > 0);
    }

    #[test]
    fn bad_input_is_refused() {
        let msg = |r: Result<Vec<[u32; 3]>>| r.unwrap_err().to_string();
        assert!(ScoreTarget::new(0, 3, vec![]).is_err());
        assert!(ScoreTarget::new(MAX_SCORE_SIDE + 1, 1, vec![0; 32769]).is_err());
        assert!(ScoreTarget::new(2, 2, vec![0; 3])
            .unwrap_err()
            .to_string()
            .contains("3 flag bytes"));
        let target = ScoreTarget::new(2, 2, vec![7; 4]).unwrap();
        let id = [FixedRigid::IDENTITY];
        let e = msg(score_transforms(
            &target,
            &[[0, 0], [1, MAX_SCORE_SIDE]],
            &id,
        ));
        assert!(e.contains("point 1") && e.contains("32768"), "{e}");
        let bad = FixedRigid {
            cos: ONE + 1,
            ..FixedRigid::IDENTITY
        };
        let e = msg(score_transforms(&target, &[[0, 0]], &[bad]));
        assert!(e.contains("transform 0"), "{e}");
        let bad = FixedRigid {
            ty: i32::MIN,
            ..FixedRigid::IDENTITY
        };
        assert!(score_transforms(&target, &[[0, 0]], &[bad]).is_err());
        let broken = ScoreTarget {
            width: 3,
            height: 2,
            flags: vec![0; 4],
        };
        assert!(score_transforms(&broken, &[], &id).is_err());
        assert!(!msg(score_transforms(&target, &[[0, 0]], &[bad])).contains('\n'));
        // Empty inputs are fine.
        assert_eq!(score_transforms(&target, &[], &id).unwrap(), [[0; 3]]);
        assert!(score_transforms(&target, &[[1, 1]], &[])
            .unwrap()
            .is_empty());
        assert_eq!(
            score_transforms(&target, &[[1, 1], [5, 5]], &id).unwrap(),
            [[1, 1, 1]]
        );
    }
}
