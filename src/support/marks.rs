//! The marks the tool leaves in the files it writes that are not robot maps (merged maps, pictures), so
//! that a folder run knows its own outputs: a rerun of `merge DIR` must not take last run's merged map or
//! report pictures for robots' maps. Each mark is invisible to other readers: a comment line in a yaml or
//! a PGM header, a `Software` text chunk in a PNG.

use std::io::Read;
use std::path::Path;

/// The comment that opens a merged map's yaml and stands in its PGM header.
pub const MERGED_MAP: &str = "ogm-corners merged map";

/// The PNG `Software` text of every picture the tool writes (overlays, report pictures, contact sheets).
pub const PICTURE: &str = "ogm-corners picture";

/// The PNG text keyword the picture mark is written under (a keyword the PNG specification registers).
pub const PNG_KEYWORD: &str = "Software";

/// What the tool wrote a file as, from its mark.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Written {
    /// A merged map (its yaml or its image).
    MergedMap,
    /// A picture: an overlay, a report's picture, a contact sheet.
    Picture,
}

impl Written {
    /// What the file is, for a note.
    pub fn describe(self) -> &'static str {
        match self {
            Written::MergedMap => "a merged map",
            Written::Picture => "a picture",
        }
    }
}

/// How much of a file's start is read for a mark: it stands in a yaml's first line, a PGM's header, a
/// PNG's chunks before its pixels, all within the first few dozen bytes of what the tool writes.
const HEAD_BYTES: u64 = 1024;

/// The first comment line of a merged map's yaml.
pub fn merged_yaml_comment() -> String {
    format!(
        "# {MERGED_MAP}: written by ogm-corners; a folder given to the tool leaves it out (name it to use it as a map)\n"
    )
}

/// What the tool wrote the file at `path` as, when it carries the tool's mark; None for any other file
/// (or one that cannot be read: the loader says why when it is used).
pub fn written_by_tool(path: &Path) -> Option<Written> {
    let mut head = Vec::new();
    std::fs::File::open(path)
        .ok()?
        .take(HEAD_BYTES)
        .read_to_end(&mut head)
        .ok()?;
    mark_in(&head)
}

/// The mark in a file's first bytes, if any.
pub fn mark_in(head: &[u8]) -> Option<Written> {
    if let Some(chunks) = head.strip_prefix(b"\x89PNG\r\n\x1a\n") {
        return png_mark(chunks);
    }
    // A yaml's or a PGM header's comment lines; a PGM's raster after its header is no comment.
    let text = String::from_utf8_lossy(head);
    text.lines()
        .take(8)
        .filter_map(|l| l.trim_start().strip_prefix('#'))
        .any(|c| c.trim_start().starts_with(MERGED_MAP))
        .then_some(Written::MergedMap)
}

/// The picture mark among a PNG's chunks before its first pixel data (`IDAT`).
fn png_mark(mut chunks: &[u8]) -> Option<Written> {
    while chunks.len() >= 8 {
        let len = u32::from_be_bytes(chunks[..4].try_into().ok()?) as usize;
        let kind = &chunks[4..8];
        if kind == b"IDAT" {
            return None;
        }
        let data = chunks.get(8..8usize.checked_add(len)?)?;
        if kind == b"tEXt" {
            let mut parts = data.splitn(2, |&b| b == 0);
            let (key, text) = (parts.next()?, parts.next().unwrap_or_default());
            if key == PNG_KEYWORD.as_bytes() && text.starts_with(PICTURE.as_bytes()) {
                return Some(Written::Picture);
            }
        }
        // The chunk's data and its CRC.
        chunks = chunks.get(8 + len + 4..)?;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_merged_yaml_and_pgm_header_are_marked_and_a_robot_map_is_not() {
        let yaml = format!("{}image: m.pgm\nresolution: 0.05\n", merged_yaml_comment());
        assert_eq!(mark_in(yaml.as_bytes()), Some(Written::MergedMap));
        let pgm = format!("P5\n# {MERGED_MAP}\n4 4\n255\n");
        assert_eq!(mark_in(pgm.as_bytes()), Some(Written::MergedMap));
        assert_eq!(mark_in(b"image: m.pgm\nresolution: 0.05\n"), None);
        assert_eq!(mark_in(b"P5\n# CREATOR: GIMP\n4 4\n255\n\x00\x00"), None);
    }

    #[test]
    fn a_picture_is_marked_in_its_png_text_and_a_cut_png_is_not_read_past_its_end() {
        let mut png = Vec::new();
        let img = image::RgbImage::new(3, 2);
        crate::support::files::encode_png(&mut png, &img).unwrap();
        assert_eq!(mark_in(&png), Some(Written::Picture));
        // The same pixels without the text chunk.
        let mut plain = Vec::new();
        {
            use image::ImageEncoder as _;
            image::codecs::png::PngEncoder::new(&mut plain)
                .write_image(img.as_raw(), 3, 2, image::ExtendedColorType::Rgb8)
                .unwrap();
        }
        assert_eq!(mark_in(&plain), None);
        for cut in 0..png.len() {
            // Never a panic on a short or damaged head.
            let _ = mark_in(&png[..cut]);
        }
    }
}
