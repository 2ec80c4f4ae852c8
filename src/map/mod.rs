//! Maps: what a robot's map is and how it is read, below everything that detects or merges.
//!
//! - [`decode`]: PGM and PNG decoders, within a memory budget;
//! - `image` and `occupancy`: [`MapImage`] (8-bit grey pixels) and [`OccupancyMap`] (a map as loaded:
//!   the image, its [`Thresholds`] and [`GeoRef`]), with the loaders ([`OccupancyMap::load`],
//!   [`load_image`]);
//! - `yaml`, `find`, `save`, `rows`, `ros_grid`: ROS `map_server` yaml files, a folder's maps, the
//!   files the tool writes, a map's rows read straight from its file, ROS `OccupancyGrid` values;
//! - [`stream`]: maps as rows, for maps larger than memory;
//! - [`states`]: the three cell states (free, occupied, unknown);
//! - [`grid`]: a map resampled on a grid turned to its walls (the robust detector's);
//! - [`synthetic`]: the seeded synthetic office and the PRNG the tests and measurements use.

pub mod decode;
mod find;
pub mod grid;
mod image;
mod occupancy;
mod ros_grid;
mod rows;
mod save;
pub mod states;
pub mod stream;
pub mod synthetic;
mod yaml;

pub use find::{find_maps, map_name, output_names, FoundMaps};
pub use image::{write_pgm_header, write_pgm_header_with, MapImage, PixelSource, MAX_IMAGE_BYTES};
pub use occupancy::{
    decode_image, load_image, load_image_within, GeoRef, OccupancyMap, Thresholds,
};
pub use ros_grid::{grid_image, GridThresholds, GRID_FREE, GRID_OCCUPIED, GRID_UNKNOWN};
pub use rows::{DecoderRows, MapRows};
pub use save::{merged_yaml_text, save_names, write_merged_pgm_to, yaml_text};
pub use yaml::{
    is_yaml, map_yaml_text, map_yaml_text_with, yaml_image, MapYaml, MAX_YAML_BYTES,
    MAX_YAML_NESTING,
};
