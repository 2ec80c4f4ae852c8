//! A map's image: 8-bit grey pixels, owned or read in place, and the PGM header the tool writes.

use std::path::Path;
use std::sync::Arc;

use crate::support::error::{Error, Result};
use crate::support::files;

/// Largest decoded image the loader accepts, in bytes: a 65536 x 65536 8-bit map. Guards against a
/// header that claims an absurd size, which would otherwise abort the process when allocating.
pub const MAX_IMAGE_BYTES: u64 = 1 << 32;

/// Pixels that live outside the library and are read in place, such as a numpy array handed in from
/// Python: the holder keeps them alive and unchanged for as long as it exists.
pub trait PixelSource: Send + Sync {
    /// The pixels, row-major, row 0 at the top.
    fn bytes(&self) -> &[u8];
}

impl PixelSource for Vec<u8> {
    fn bytes(&self) -> &[u8] {
        self
    }
}

/// Where a map's pixels are: owned, or read in place from a [`PixelSource`] (copied on first write).
#[derive(Clone)]
enum Pixels {
    Owned(Vec<u8>),
    Shared(Arc<dyn PixelSource>),
}

impl Pixels {
    fn bytes(&self) -> &[u8] {
        match self {
            Pixels::Owned(v) => v,
            Pixels::Shared(s) => s.bytes(),
        }
    }
}

/// An 8-bit greyscale map image, row-major, row 0 at the top.
#[derive(Clone)]
pub struct MapImage {
    width: u32,
    height: u32,
    pixels: Pixels,
}

impl PartialEq for MapImage {
    fn eq(&self, other: &Self) -> bool {
        (self.width, self.height) == (other.width, other.height) && self.pixels() == other.pixels()
    }
}

impl Eq for MapImage {}

impl std::fmt::Debug for MapImage {
    /// The size and where the pixels are, not the pixels.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let kind = match self.pixels {
            Pixels::Owned(_) => "owned",
            Pixels::Shared(_) => "shared",
        };
        write!(f, "MapImage({}x{}, {kind})", self.width, self.height)
    }
}

impl MapImage {
    /// Wraps `pixels` (row-major, `width * height` bytes). Fails on a zero-size map or a length mismatch.
    pub fn new(width: u32, height: u32, pixels: Vec<u8>) -> Result<Self> {
        check_len(width, height, pixels.len())?;
        Ok(MapImage {
            width,
            height,
            pixels: Pixels::Owned(pixels),
        })
    }

    /// Wraps pixels read in place (`width * height` bytes from `source`), without a copy; the first
    /// [`MapImage::pixels_mut`] copies them. Fails as [`MapImage::new`] does.
    pub fn shared(width: u32, height: u32, source: Arc<dyn PixelSource>) -> Result<Self> {
        check_len(width, height, source.bytes().len())?;
        Ok(MapImage {
            width,
            height,
            pixels: Pixels::Shared(source),
        })
    }

    /// A map of one value everywhere.
    pub fn filled(width: u32, height: u32, value: u8) -> Result<Self> {
        Self::new(width, height, vec![value; width as usize * height as usize])
    }

    /// Width in pixels (at least 1).
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels (at least 1).
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The pixels, row-major, row 0 at the top.
    pub fn pixels(&self) -> &[u8] {
        self.pixels.bytes()
    }

    /// Mutable pixels, for building maps in memory (pixels read in place are copied first).
    pub fn pixels_mut(&mut self) -> &mut [u8] {
        if let Pixels::Shared(s) = &self.pixels {
            self.pixels = Pixels::Owned(s.bytes().to_vec());
        }
        match &mut self.pixels {
            Pixels::Owned(v) => v,
            Pixels::Shared(_) => unreachable!("copied above"),
        }
    }

    /// The same image with its pixels behind a reference count, so that its clones share them (the maps
    /// a Python program passes around).
    pub fn into_shared(self) -> MapImage {
        match self.pixels {
            Pixels::Owned(v) => MapImage {
                pixels: Pixels::Shared(Arc::new(v)),
                ..self
            },
            Pixels::Shared(_) => self,
        }
    }

    /// Whether the pixels are read in place from a [`PixelSource`] rather than owned.
    pub fn is_shared(&self) -> bool {
        matches!(self.pixels, Pixels::Shared(_))
    }

    /// The pixel at column `x`, row `y`. Panics when out of range, like slice indexing.
    pub fn get(&self, x: u32, y: u32) -> u8 {
        self.pixels()[y as usize * self.width as usize + x as usize]
    }

    /// Number of pixels.
    pub fn len(&self) -> usize {
        self.pixels().len()
    }

    /// Always false: a `MapImage` has at least one pixel.
    pub fn is_empty(&self) -> bool {
        self.pixels().is_empty()
    }

    /// Writes the map as a binary PGM (P5), atomically ([`files::write_atomic`]), without a second copy
    /// of the pixels.
    pub fn write_pgm(&self, path: &Path) -> Result<()> {
        files::write_atomic(path, |out| self.write_pgm_to(out))
    }

    /// The image as a binary PGM (P5, maxval 255) into `out`.
    pub fn write_pgm_to(&self, out: &mut dyn std::io::Write) -> std::io::Result<()> {
        write_pgm_header(out, self.width, self.height)?;
        out.write_all(self.pixels())
    }
}

/// The header of a binary PGM (P5, maxval 255) of `width` x `height`; the raster follows it.
pub fn write_pgm_header(
    out: &mut dyn std::io::Write,
    width: u32,
    height: u32,
) -> std::io::Result<()> {
    write_pgm_header_with(out, width, height, None)
}

/// [`write_pgm_header`] with a comment line after the magic number (which every PGM reader skips).
pub fn write_pgm_header_with(
    out: &mut dyn std::io::Write,
    width: u32,
    height: u32,
    comment: Option<&str>,
) -> std::io::Result<()> {
    out.write_all(b"P5\n")?;
    if let Some(c) = comment {
        writeln!(out, "# {c}")?;
    }
    write!(out, "{width} {height}\n255\n")
}

/// Refuses a zero-size map or a pixel count other than `width * height`.
fn check_len(width: u32, height: u32, len: usize) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(Error::invalid(format!(
            "zero-size map ({width}x{height}): nothing to detect in"
        )));
    }
    let expected = width as u64 * height as u64;
    if len as u64 != expected {
        return Err(Error::invalid(format!(
            "map of {width}x{height} needs {expected} pixels, got {len}"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shared_pixels_are_read_in_place_and_copied_on_write() {
        let source: Arc<dyn PixelSource> = Arc::new(vec![1u8, 2, 3, 4, 5, 6]);
        let img = MapImage::shared(3, 2, source.clone()).unwrap();
        assert!(img.is_shared());
        assert_eq!(img.pixels().as_ptr(), source.bytes().as_ptr());
        assert_eq!(img.get(2, 1), 6);
        // A clone shares the pixels; a write copies them first and leaves the source alone.
        let mut copy = img.clone();
        assert_eq!(copy.pixels().as_ptr(), source.bytes().as_ptr());
        copy.pixels_mut()[0] = 9;
        assert!(!copy.is_shared());
        assert_eq!(source.bytes()[0], 1);
        assert_ne!(copy, img);
        assert_eq!(MapImage::new(3, 2, vec![1, 2, 3, 4, 5, 6]).unwrap(), img);
        assert!(MapImage::shared(4, 2, source).is_err());
        // An owned image made shared keeps its pixels and shares them from then on.
        let owned = MapImage::new(2, 1, vec![7, 8]).unwrap().into_shared();
        assert!(owned.is_shared() && owned.pixels() == [7, 8]);
        assert_eq!(owned.clone().pixels().as_ptr(), owned.pixels().as_ptr());
    }
}
