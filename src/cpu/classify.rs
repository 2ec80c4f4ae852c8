//! CPU twin of the classification kernel: each pixel value becomes a [`CellState`] through the table.

use crate::map::MapImage;
use crate::states::{CellState, ClassTable};

/// The state of every pixel of `image`, row-major.
pub fn classify(image: &MapImage, table: &ClassTable) -> Vec<CellState> {
    image.pixels().iter().map(|&v| table.state(v)).collect()
}
