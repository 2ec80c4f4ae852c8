//! Maps: what a robot's map is and how it is read, below everything that detects or merges.
//!
//! - `image.rs`: [`MapImage`], a map's pixels (8-bit grey);
//! - `occupancy.rs`: [`OccupancyMap`], a map as loaded, header first and bounded: the image, its
//!   [`Thresholds`] and [`GeoRef`], with the loaders ([`OccupancyMap::load`], [`load_image`]);
//! - `yaml.rs`: ROS `map_server` yaml files; `find.rs`: folder search, a folder's maps; `rows.rs`: a map
//!   opened to be read row by row, its rows read straight from its file; `ros_grid.rs`: ROS
//!   `nav_msgs/OccupancyGrid` cells to and from map images (as `map_saver` and `map_server` do);
//!   `save.rs`: the files the tool writes, a map as yaml + PGM;
//! - [`decode`] (`decode/`): the strict row-by-row PGM (`pgm.rs`) and PNG (`png.rs`) decoders, within a
//!   memory budget;
//! - [`states`] (`states.rs`): the three cell states (free, occupied, unknown) and the pixel-value table,
//!   `ClassTable`;
//! - [`stream`] (`stream/`): maps as rows and windows of rows, with their reader thread, for maps larger
//!   than memory;
//! - [`grid`] (`grid.rs`): the rotated sampling grid, in integer arithmetic, that every backend samples
//!   through: a map resampled on a grid turned to its walls (the robust detector's);
//! - [`synthetic`] (`synthetic.rs`): the seeded synthetic office used by `demo`, tests and benchmarks (the
//!   project ships no real maps), and the PRNG the tests and measurements use.

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
