//! A map's preparation ([`Prepared`]) and pre-screen signature ([`Signature`]) as bytes, so that a
//! distributed run prepares each map once, on whichever worker, and hands the preparation to every
//! worker that aligns a pair with it (the Python `ogm_corners.distributed`).
//!
//! Exact: every float is written as its bits, so a preparation read back aligns to the same result, to
//! the bit, as the one written. Checked: a version, a checksum (XXH3-64) and every invariant the
//! aligner relies on (array lengths, points inside the crop, the nearest-wall indices) are checked on
//! reading, and a length is checked against the bytes left before anything is allocated, so damaged or
//! foreign bytes are a clear error, never a panic or an unbounded allocation.
//!
//! Two forms: the whole preparation, and the part a placement reads ([`Form::Placement`]: without the
//! nearest-wall indices, the screening flags and the coarse masks, about 3 bytes a pixel instead
//! of 12), for the process that places the maps while workers align them.

use crate::backend::ScoreTarget;
use crate::merge::many::prescreen::Signature;
use crate::merge::pair::prepare::{Coarse, Prepared, CELLS};
use crate::support::error::{Error, Result};

const PREPARED_MAGIC: &[u8; 8] = b"OGMPREP\0";
const SIGNATURE_MAGIC: &[u8; 8] = b"OGMSIGN\0";
/// Bumped whenever the layout or the preparation's content changes.
const VERSION: u32 = 3;

/// What [`encode_prepared`] writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Form {
    /// Everything: it can be aligned.
    Full,
    /// What a placement reads (dense checks, predicted overlaps): it cannot be aligned.
    Placement,
}

/// `p` as bytes in `form`.
pub fn encode_prepared(p: &Prepared, form: Form) -> Vec<u8> {
    let full = form == Form::Full;
    let px = p.w * p.h;
    let mut w = Writer::with_capacity(64 + px * if full { 13 } else { 3 });
    w.bytes(PREPARED_MAGIC);
    w.u32(VERSION);
    w.u8(u8::from(!full));
    w.f64(p.off.0);
    w.f64(p.off.1);
    w.u64(p.w as u64);
    w.u64(p.h as u64);
    w.pairs(&p.walls);
    for pts in [&p.wall_points, &p.screen_points, &p.free_points] {
        w.points(pts);
    }
    w.target(&p.flags);
    w.target(&p.flags_fine);
    w.target(&p.flags_free);
    for r in p.reference {
        w.f64(r.0);
        w.f64(r.1);
    }
    w.f64(p.angle);
    match &p.corners {
        Some(c) => {
            w.u8(1);
            w.pairs(c);
        }
        None => w.u8(0),
    }
    if full {
        w.target(&p.flags_screen);
        w.u32s(&p.nearest);
        w.u64(p.levels.len() as u64);
        for level in &p.levels {
            match level {
                Some(c) => {
                    w.u8(1);
                    w.u64(c.cell as u64);
                    w.u64(c.cw as u64);
                    w.u64(c.ch as u64);
                    w.f32s(&c.cwall);
                    w.f32s(&c.cwall_dil);
                    w.f32s(&c.cfree);
                }
                None => w.u8(0),
            }
        }
    }
    w.finish()
}

/// A preparation written by [`encode_prepared`], checked, and its form.
pub fn decode_prepared(bytes: &[u8]) -> Result<(Prepared, Form)> {
    let mut r = Reader::open(bytes, PREPARED_MAGIC, "a map's preparation")?;
    let form = match r.u8()? {
        0 => Form::Full,
        1 => Form::Placement,
        k => return Err(r.bad(format!("unknown form {k}"))),
    };
    let off = (r.f64()?, r.f64()?);
    let (w, h) = (r.usize()?, r.usize()?);
    let px = w
        .checked_mul(h)
        .filter(|&px| px <= bytes.len().saturating_mul(8) + 64)
        .ok_or_else(|| r.bad(format!("a {w} x {h} crop")))?;
    if !(off.0.is_finite() && off.1.is_finite()) {
        return Err(r.bad("a crop origin that is not finite"));
    }
    let walls = r.wall_pixels(w, h)?;
    let wall_points = r.points(w, h)?;
    let screen_points = r.points(w, h)?;
    let free_points = r.points(w, h)?;
    let flags = r.target(w, h)?;
    let flags_fine = r.target(w, h)?;
    let flags_free = r.target(w, h)?;
    let mut reference = [(0.0, 0.0); 5];
    for p in &mut reference {
        *p = (r.f64()?, r.f64()?);
    }
    let angle = r.f64()?;
    let corners = match r.u8()? {
        0 => None,
        1 => Some(r.pairs()?),
        k => return Err(r.bad(format!("a corner flag of {k}"))),
    };
    let finite = |ps: &[(f64, f64)]| ps.iter().all(|p| p.0.is_finite() && p.1.is_finite());
    if !(finite(&walls) && finite(&reference) && angle.is_finite())
        || corners.as_deref().is_some_and(|c| !finite(c))
    {
        return Err(r.bad("a coordinate that is not finite"));
    }
    let (flags_screen, nearest, levels) = match form {
        Form::Placement => (
            ScoreTarget {
                width: flags.width,
                height: flags.height,
                flags: Vec::new(),
            },
            Vec::new(),
            Vec::new(),
        ),
        Form::Full => {
            let flags_screen = r.target(w, h)?;
            let nearest = r.u32s()?;
            if nearest.len() != px {
                return Err(r.bad("nearest-wall indices of another size than the crop"));
            }
            if nearest.iter().any(|&i| i != u32::MAX && i as usize >= px) {
                return Err(r.bad("a nearest-wall index outside the crop"));
            }
            let n = r.usize()?;
            if n > CELLS.len() {
                return Err(r.bad(format!("{n} coarse levels")));
            }
            let mut levels = Vec::with_capacity(n);
            for _ in 0..n {
                levels.push(match r.u8()? {
                    0 => None,
                    1 => {
                        let (cell, cw, ch) = (r.usize()?, r.usize()?, r.usize()?);
                        if !CELLS.contains(&cell)
                            || cw != w.div_ceil(cell)
                            || ch != h.div_ceil(cell)
                        {
                            return Err(
                                r.bad(format!("a coarse level of {cw} x {ch} cells of {cell} px"))
                            );
                        }
                        let (cwall, cwall_dil, cfree) = (r.f32s()?, r.f32s()?, r.f32s()?);
                        if [&cwall, &cwall_dil, &cfree]
                            .iter()
                            .any(|v| v.len() != cw * ch)
                        {
                            return Err(r.bad("coarse masks of another size than their level"));
                        }
                        Some(Coarse {
                            cell,
                            cw,
                            ch,
                            cwall,
                            cwall_dil,
                            cfree,
                        })
                    }
                    k => return Err(r.bad(format!("a level flag of {k}"))),
                });
            }
            (flags_screen, nearest, levels)
        }
    };
    r.end()?;
    Ok((
        Prepared {
            off,
            w,
            h,
            walls,
            wall_points,
            screen_points,
            flags,
            flags_fine,
            flags_screen,
            free_points,
            flags_free,
            nearest,
            reference,
            angle,
            corners,
            symmetry: std::sync::OnceLock::new(),
            levels,
        },
        form,
    ))
}

/// `s` as bytes.
pub fn encode_signature(s: &Signature) -> Vec<u8> {
    let mut w = Writer::with_capacity(32 + s.terms.len() * 8);
    w.bytes(SIGNATURE_MAGIC);
    w.u32(VERSION);
    w.u64(s.corners as u64);
    w.u64(s.terms.len() as u64);
    for &(t, v) in &s.terms {
        w.u32(t);
        w.u32(v.to_bits());
    }
    w.finish()
}

/// A signature written by [`encode_signature`], checked (terms ascending, weights finite).
pub fn decode_signature(bytes: &[u8]) -> Result<Signature> {
    let mut r = Reader::open(bytes, SIGNATURE_MAGIC, "a map's signature")?;
    let corners = r.usize()?;
    let n = r.len(8)?;
    let mut terms = Vec::with_capacity(n);
    for _ in 0..n {
        terms.push((r.u32()?, f32::from_bits(r.u32()?)));
    }
    if terms.windows(2).any(|t| t[0].0 >= t[1].0) || terms.iter().any(|t| !t.1.is_finite()) {
        return Err(r.bad("terms out of order or weights not finite"));
    }
    r.end()?;
    Ok(Signature { terms, corners })
}

struct Writer(Vec<u8>);

impl Writer {
    fn with_capacity(n: usize) -> Writer {
        Writer(Vec::with_capacity(n))
    }
    fn bytes(&mut self, b: &[u8]) {
        self.0.extend_from_slice(b);
    }
    fn u8(&mut self, v: u8) {
        self.0.push(v);
    }
    fn u32(&mut self, v: u32) {
        self.bytes(&v.to_le_bytes());
    }
    fn u64(&mut self, v: u64) {
        self.bytes(&v.to_le_bytes());
    }
    fn f64(&mut self, v: f64) {
        self.u64(v.to_bits());
    }
    fn pairs(&mut self, ps: &[(f64, f64)]) {
        self.u64(ps.len() as u64);
        for p in ps {
            self.f64(p.0);
            self.f64(p.1);
        }
    }
    fn points(&mut self, ps: &[[u32; 2]]) {
        self.u64(ps.len() as u64);
        for p in ps {
            self.u32(p[0]);
            self.u32(p[1]);
        }
    }
    fn f32s(&mut self, v: &[f32]) {
        self.u64(v.len() as u64);
        for x in v {
            self.bytes(&x.to_bits().to_le_bytes());
        }
    }
    fn u32s(&mut self, v: &[u32]) {
        self.u64(v.len() as u64);
        for x in v {
            self.bytes(&x.to_le_bytes());
        }
    }
    fn target(&mut self, t: &ScoreTarget) {
        self.u32(t.width);
        self.u32(t.height);
        self.u64(t.flags.len() as u64);
        self.bytes(&t.flags);
    }
    /// The bytes with their checksum.
    fn finish(mut self) -> Vec<u8> {
        let sum = xxhash_rust::xxh3::xxh3_64(&self.0);
        self.u64(sum);
        self.0
    }
}

struct Reader<'a> {
    rest: &'a [u8],
    what: &'static str,
}

impl<'a> Reader<'a> {
    /// Checks the magic, the version and the checksum.
    fn open(bytes: &'a [u8], magic: &[u8; 8], what: &'static str) -> Result<Reader<'a>> {
        let bad = |why: &str| Error::invalid(format!("not {what} written by this version: {why}"));
        if bytes.len() < 20 || &bytes[..8] != magic {
            return Err(bad("no header"));
        }
        let (body, sum) = bytes.split_at(bytes.len() - 8);
        if xxhash_rust::xxh3::xxh3_64(body).to_le_bytes() != sum {
            return Err(bad("its checksum does not match (damaged)"));
        }
        let version = u32::from_le_bytes(body[8..12].try_into().expect("4 bytes"));
        if version != VERSION {
            return Err(bad(&format!(
                "format version {version}, this build reads {VERSION}"
            )));
        }
        Ok(Reader {
            rest: &body[12..],
            what,
        })
    }
    fn bad(&self, why: impl std::fmt::Display) -> Error {
        Error::invalid(format!("not a valid encoding of {}: {why}", self.what))
    }
    fn take(&mut self, n: usize) -> Result<&'a [u8]> {
        if n > self.rest.len() {
            return Err(self.bad("it ends early"));
        }
        let (head, tail) = self.rest.split_at(n);
        self.rest = tail;
        Ok(head)
    }
    fn u8(&mut self) -> Result<u8> {
        Ok(self.take(1)?[0])
    }
    fn u32(&mut self) -> Result<u32> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().expect("4")))
    }
    fn u64(&mut self) -> Result<u64> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().expect("8")))
    }
    fn usize(&mut self) -> Result<usize> {
        let v = self.u64()?;
        usize::try_from(v).map_err(|_| self.bad(format!("a size of {v}")))
    }
    fn f64(&mut self) -> Result<f64> {
        Ok(f64::from_bits(self.u64()?))
    }
    /// A count of items of `size` bytes, checked against the bytes left before anything is allocated.
    fn len(&mut self, size: usize) -> Result<usize> {
        let n = self.usize()?;
        if n.checked_mul(size).is_none_or(|b| b > self.rest.len()) {
            return Err(self.bad(format!("{n} items in {} bytes", self.rest.len())));
        }
        Ok(n)
    }
    /// Pairs that are pixels of a `w` x `h` crop (whole coordinates inside it): a map's wall pixels,
    /// at which the aligner reads the map's own flags.
    fn wall_pixels(&mut self, w: usize, h: usize) -> Result<Vec<(f64, f64)>> {
        let walls = self.pairs()?;
        let pixel_of_crop = |&(x, y): &(f64, f64)| {
            x >= 0.0
                && y >= 0.0
                && x < w as f64
                && y < h as f64
                && x.fract() == 0.0
                && y.fract() == 0.0
        };
        if !walls.iter().all(pixel_of_crop) {
            return Err(self.bad("a wall pixel outside the crop"));
        }
        Ok(walls)
    }

    fn pairs(&mut self) -> Result<Vec<(f64, f64)>> {
        let n = self.len(16)?;
        (0..n).map(|_| Ok((self.f64()?, self.f64()?))).collect()
    }
    fn points(&mut self, w: usize, h: usize) -> Result<Vec<[u32; 2]>> {
        let n = self.len(8)?;
        let b = self.take(n * 8)?;
        let pts: Vec<[u32; 2]> = b
            .chunks_exact(8)
            .map(|c| {
                [
                    u32::from_le_bytes(c[..4].try_into().expect("4")),
                    u32::from_le_bytes(c[4..].try_into().expect("4")),
                ]
            })
            .collect();
        if pts.iter().any(|p| p[0] as usize >= w || p[1] as usize >= h) {
            return Err(self.bad("a point outside the crop"));
        }
        Ok(pts)
    }
    fn f32s(&mut self) -> Result<Vec<f32>> {
        let n = self.len(4)?;
        let b = self.take(n * 4)?;
        Ok(b.chunks_exact(4)
            .map(|c| f32::from_bits(u32::from_le_bytes(c.try_into().expect("4"))))
            .collect())
    }
    fn u32s(&mut self) -> Result<Vec<u32>> {
        let n = self.len(4)?;
        let b = self.take(n * 4)?;
        Ok(b.chunks_exact(4)
            .map(|c| u32::from_le_bytes(c.try_into().expect("4")))
            .collect())
    }
    /// A `w` x `h` scoring target.
    fn target(&mut self, w: usize, h: usize) -> Result<ScoreTarget> {
        let (tw, th) = (self.u32()?, self.u32()?);
        let n = self.len(1)?;
        let flags = self.take(n)?.to_vec();
        if tw as usize != w || th as usize != h || n != w * h {
            return Err(self.bad("flags of another size than the crop"));
        }
        let t = ScoreTarget {
            width: tw,
            height: th,
            flags,
        };
        t.check().map_err(|e| self.bad(e))?;
        Ok(t)
    }
    fn end(&self) -> Result<()> {
        if self.rest.is_empty() {
            Ok(())
        } else {
            Err(self.bad(format!("{} bytes after its end", self.rest.len())))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::merge::pair::align::{align_prepared, MergeOptions};

    fn two() -> (Prepared, Prepared, Vec<crate::map::OccupancyMap>) {
        let (_, maps, _) = crate::measure::merging::many::synthetic_maps(2, 7).unwrap();
        (Prepared::new(&maps[0]), Prepared::new(&maps[1]), maps)
    }

    #[test]
    fn a_preparation_read_back_aligns_to_the_same_bits() {
        let (a, b, _) = two();
        let bytes = encode_prepared(&a, Form::Full);
        let (back, form) = decode_prepared(&bytes).unwrap();
        assert_eq!(form, Form::Full);
        assert_eq!(encode_prepared(&back, Form::Full), bytes);
        let options = MergeOptions::default();
        let want = align_prepared(&a, &b, &options).unwrap();
        let got = align_prepared(&back, &b, &options).unwrap();
        assert_eq!(format!("{want:?}"), format!("{got:?}"));
        assert!(want.accepted);
    }

    #[test]
    fn the_placement_form_is_small_and_cannot_be_aligned() {
        let (a, b, _) = two();
        let full = encode_prepared(&a, Form::Full);
        let light = encode_prepared(&a, Form::Placement);
        // Three flag bytes a pixel against the whole preparation's twelve or so.
        assert!(
            light.len() * 2 < full.len(),
            "{} {}",
            light.len(),
            full.len()
        );
        let (back, form) = decode_prepared(&light).unwrap();
        assert_eq!(form, Form::Placement);
        assert_eq!(encode_prepared(&back, Form::Placement), light);
        let e = align_prepared(&back, &b, &MergeOptions::default()).unwrap_err();
        assert!(e.to_string().contains("placement form"), "{e}");
        // What a placement reads is there: the predicted overlap is the same.
        let t = crate::merge::Rigid::IDENTITY;
        assert_eq!(
            crate::merge::many::prescreen::predicted_overlap(&back, &b, &t),
            crate::merge::many::prescreen::predicted_overlap(&a, &b, &t)
        );
    }

    #[test]
    fn damaged_or_foreign_bytes_are_clear_errors() {
        let (a, _, maps) = two();
        let bytes = encode_prepared(&a, Form::Placement);
        // Cut anywhere, or one byte changed anywhere: an error, never a panic.
        for cut in (0..bytes.len()).step_by(bytes.len() / 97 + 1) {
            assert!(decode_prepared(&bytes[..cut]).is_err(), "cut at {cut}");
        }
        for at in (0..bytes.len()).step_by(bytes.len() / 89 + 1) {
            let mut b = bytes.clone();
            b[at] ^= 0x40;
            assert!(decode_prepared(&b).is_err(), "byte {at}");
        }
        let s = crate::merge::many::prescreen::Signature::of(&maps[0]).unwrap();
        let sb = encode_signature(&s);
        assert_eq!(decode_signature(&sb).unwrap(), s);
        let e = decode_prepared(&sb).err().unwrap().to_string();
        assert!(e.contains("not a map's preparation"), "{e}");
        // A well-formed body that lies (a point outside the crop), with a good checksum: refused.
        // Its head: a placement form's 2 x 2 crop at the origin, then its walls.
        let lie_with_walls = |walls: &[(f64, f64)]| {
            let mut lie = Writer::with_capacity(64);
            lie.bytes(PREPARED_MAGIC);
            lie.u32(VERSION);
            lie.u8(1);
            lie.f64(0.0);
            lie.f64(0.0);
            lie.u64(2);
            lie.u64(2);
            lie.pairs(walls);
            lie
        };
        let mut lie = lie_with_walls(&[]);
        lie.points(&[[5, 0]]);
        let e = decode_prepared(&lie.finish()).err().unwrap().to_string();
        assert!(e.contains("a point outside the crop"), "{e}");
        // ... or a wall pixel outside it (or between pixels): refused, as the aligner reads the map's
        // flags there.
        for wall in [(2.0, 0.0), (0.0, -1.0), (0.5, 1.0)] {
            let e = decode_prepared(&lie_with_walls(&[wall]).finish())
                .err()
                .unwrap()
                .to_string();
            assert!(e.contains("a wall pixel outside the crop"), "{wall:?}: {e}");
        }
        // Bytes of another version of the format: refused, naming both versions.
        let mut old = Writer::with_capacity(64);
        old.bytes(PREPARED_MAGIC);
        old.u32(VERSION - 1);
        old.u8(1);
        let e = decode_prepared(&old.finish()).err().unwrap().to_string();
        assert!(
            e.contains(&format!("format version {}", VERSION - 1)),
            "{e}"
        );
        // A huge count is refused before anything is allocated.
        let mut huge = Writer::with_capacity(64);
        huge.bytes(SIGNATURE_MAGIC);
        huge.u32(VERSION);
        huge.u64(3);
        huge.u64(u64::MAX / 2);
        let e = decode_signature(&huge.finish()).unwrap_err().to_string();
        assert!(e.contains("items in"), "{e}");
    }
}
