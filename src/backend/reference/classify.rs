//! CPU twin of the classification kernel: each pixel value becomes a [`CellState`] through the table.

use crate::map::states::{CellState, ClassTable};
use crate::map::MapImage;

/// The state of every pixel of `image`, row-major.
pub fn classify(image: &MapImage, table: &ClassTable) -> Vec<CellState> {
    image.pixels().iter().map(|&v| table.state(v)).collect()
}
