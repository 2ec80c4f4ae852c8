//! ROS `nav_msgs/OccupancyGrid` cells to and from map images, as ROS does it: the grid's int8 cells (-1
//! unknown, 0..100 the probability of occupancy, row 0 at the BOTTOM) become the trinary image that
//! `map_saver` writes (0 occupied, 205 unknown, 254 free, row 0 at the top), and a map image becomes the
//! cells `map_server` publishes (100, -1, 0).
//!
//! A node can so hand `msg.data` to the detector and the merger, and publish a merged map, with the same
//! results as saving the grid with `map_saver` and running the tool on the files.

use rayon::prelude::*;

use super::{GeoRef, MapImage, OccupancyMap, Thresholds};
use crate::map::states::{CellState, ClassTable};
use crate::support::error::{Error, Result};

/// The grid value of an unknown cell.
pub const GRID_UNKNOWN: i8 = -1;
/// The grid value of a free cell.
pub const GRID_FREE: i8 = 0;
/// The grid value of an occupied cell.
pub const GRID_OCCUPIED: i8 = 100;

/// How grid cells become three states, as `map_saver` reads them: free when `0 <= v <= free_thresh * 100`,
/// occupied when `v >= occupied_thresh * 100` (both thresholds rounded to whole cells, as `map_saver`
/// does), unknown otherwise (-1, any other negative value, values between the thresholds).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridThresholds {
    /// Occupied from this probability up (nav2 `map_saver`'s default 0.65).
    pub occupied_thresh: f64,
    /// Free up to this probability (nav2 `map_saver`'s default 0.25).
    pub free_thresh: f64,
}

impl Default for GridThresholds {
    /// nav2 `map_saver`'s defaults: occupied from 65, free up to 25.
    fn default() -> Self {
        GridThresholds {
            occupied_thresh: 0.65,
            free_thresh: 0.25,
        }
    }
}

impl GridThresholds {
    /// The thresholds as whole cell values (free up to, occupied from), after checking both lie in [0, 1]
    /// and free_thresh does not exceed occupied_thresh.
    pub fn cell_values(&self) -> Result<(i32, i32)> {
        Thresholds {
            negate: false,
            occupied_thresh: self.occupied_thresh,
            free_thresh: self.free_thresh,
        }
        .validate()
        .map_err(Error::invalid)?;
        Ok((
            (self.free_thresh * 100.0).round() as i32,
            (self.occupied_thresh * 100.0).round() as i32,
        ))
    }

    /// The state of each grid byte (the int8 cell read as u8: -1 is 255), for detecting in grid cells
    /// in place ([`crate::Detector::detect_classified`]).
    pub fn class_table(&self) -> Result<ClassTable> {
        let (free, occupied) = self.cell_values()?;
        let mut states = [CellState::Unknown; 256];
        for (b, s) in states.iter_mut().enumerate() {
            let v = i32::from(b as u8 as i8);
            *s = if (0..=free).contains(&v) {
                CellState::Free
            } else if v >= occupied {
                CellState::Occupied
            } else {
                CellState::Unknown
            };
        }
        Ok(ClassTable::from_states(states))
    }
}

impl GeoRef {
    /// A georeference after checking it: a finite positive resolution, a finite origin x and y (a
    /// non-finite yaw is read as 0, as in the yaml loader).
    pub fn checked(resolution: f64, origin: [f64; 3]) -> Result<GeoRef> {
        if !(resolution.is_finite() && resolution > 0.0) {
            return Err(Error::invalid(format!(
                "resolution must be a finite positive number, got {resolution}"
            )));
        }
        if !(origin[0].is_finite() && origin[1].is_finite()) {
            return Err(Error::invalid(format!(
                "origin x and y must be finite, got [{}, {}]",
                origin[0], origin[1]
            )));
        }
        Ok(GeoRef { resolution, origin })
    }
}

/// Checks a grid's size against its cell count: `width * height` cells, neither zero.
fn check_grid(cells: usize, width: u32, height: u32) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(Error::invalid(format!(
            "zero-size grid ({width}x{height}): an occupancy grid needs cells"
        )));
    }
    let expected = u64::from(width) * u64::from(height);
    if cells as u64 != expected {
        return Err(Error::invalid(format!(
            "an occupancy grid of {width}x{height} has {expected} cells, got {cells}"
        )));
    }
    Ok(())
}

/// The trinary image of grid `cells` (int8 values as bytes, row-major, `width * height`), drawn as
/// `map_saver` draws it: 0 occupied, 205 unknown, 254 free; grid row 0 (the ROS layout's bottom row) is
/// the image's bottom row.
pub fn grid_image(
    cells: &[u8],
    width: u32,
    height: u32,
    thresholds: &GridThresholds,
) -> Result<MapImage> {
    check_grid(cells.len(), width, height)?;
    let value = thresholds.class_table()?.map_server_values();
    let w = width as usize;
    let mut pixels = vec![0u8; cells.len()];
    pixels.par_chunks_mut(w).enumerate().for_each(|(r, row)| {
        let src = height as usize - 1 - r;
        for (p, &c) in row.iter_mut().zip(&cells[src * w..(src + 1) * w]) {
            *p = value[c as usize];
        }
    });
    MapImage::new(width, height, pixels)
}

impl OccupancyMap {
    /// A map from a `nav_msgs/OccupancyGrid` as it arrives: `cells` its int8 data as bytes (row 0 at the
    /// bottom), its size, resolution (metres a cell) and origin (x, y, yaw of the lower-left cell's outer
    /// corner). The image is the one `map_saver` would write with `thresholds`, read back with the ROS
    /// defaults, so everything downstream matches the tool run on the saved files.
    pub fn from_occupancy_grid(
        cells: &[u8],
        width: u32,
        height: u32,
        resolution: f64,
        origin: [f64; 3],
        thresholds: &GridThresholds,
    ) -> Result<OccupancyMap> {
        let georef = GeoRef::checked(resolution, origin)?;
        georef
            .check_finite(width.max(1), height.max(1))
            .map_err(Error::invalid)?;
        let image = grid_image(cells, width, height, thresholds)?;
        Ok(OccupancyMap {
            georef: Some(georef),
            ..OccupancyMap::from_image(image)
        })
    }

    /// The map as `nav_msgs/OccupancyGrid` data, as `map_server` publishes a trinary map: row 0 at the
    /// bottom, 100 occupied, 0 free, -1 unknown (each pixel read with the map's thresholds).
    pub fn to_occupancy_grid(&self) -> Vec<i8> {
        let classes = ClassTable::new(&self.thresholds);
        let value: Vec<i8> = (0..=255u8)
            .map(|v| match classes.state(v) {
                CellState::Free => GRID_FREE,
                CellState::Occupied => GRID_OCCUPIED,
                CellState::Unknown => GRID_UNKNOWN,
            })
            .collect();
        let (w, h) = (self.image.width() as usize, self.image.height() as usize);
        let pixels = self.image.pixels();
        let mut cells = vec![0i8; w * h];
        cells.par_chunks_mut(w).enumerate().for_each(|(r, row)| {
            let src = &pixels[(h - 1 - r) * w..(h - r) * w];
            for (c, &p) in row.iter_mut().zip(src) {
                *c = value[p as usize];
            }
        });
        cells
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn as_bytes(v: &[i8]) -> Vec<u8> {
        v.iter().map(|&c| c as u8).collect()
    }

    #[test]
    fn grid_cells_read_as_map_saver_reads_them() {
        let t = GridThresholds::default().class_table().unwrap();
        let state = |v: i8| t.state(v as u8);
        assert_eq!(state(-1), CellState::Unknown);
        assert_eq!(state(-100), CellState::Unknown);
        assert_eq!(state(0), CellState::Free);
        assert_eq!(state(25), CellState::Free);
        assert_eq!(state(26), CellState::Unknown);
        assert_eq!(state(64), CellState::Unknown);
        assert_eq!(state(65), CellState::Occupied);
        assert_eq!(state(100), CellState::Occupied);
        assert_eq!(state(127), CellState::Occupied);
    }

    #[test]
    fn round_trip_flips_rows_and_keeps_three_states() {
        // 3 wide, 2 high; grid row 0 (bottom) is [-1, 0, 100].
        let grid: Vec<i8> = vec![-1, 0, 100, 100, 50, 10];
        let map = OccupancyMap::from_occupancy_grid(
            &as_bytes(&grid),
            3,
            2,
            0.05,
            [1.0, 2.0, 0.0],
            &GridThresholds::default(),
        )
        .unwrap();
        // Image row 0 is the grid's top row.
        assert_eq!(map.image.pixels(), &[0, 205, 254, 205, 254, 0]);
        assert_eq!(map.georef.unwrap().resolution, 0.05);
        assert_eq!(map.to_occupancy_grid(), vec![-1, 0, 100, 100, -1, 0]);
        // Grid cell (x 2, row 0) is the lower-right cell: its centre in the world.
        let (wx, wy) = map.georef.unwrap().pixel_to_world(2, 1, 2);
        assert!((wx - (1.0 + 2.5 * 0.05)).abs() < 1e-12 && (wy - (2.0 + 0.5 * 0.05)).abs() < 1e-12);
    }

    #[test]
    fn bad_grids_are_refused_in_one_line() {
        let t = GridThresholds::default();
        let e = |r: Result<OccupancyMap>| r.unwrap_err().to_string();
        let ok = [0u8; 6];
        assert!(e(OccupancyMap::from_occupancy_grid(
            &ok, 4, 2, 0.05, [0.0; 3], &t
        ))
        .contains("has 8 cells, got 6"));
        assert!(e(OccupancyMap::from_occupancy_grid(
            &[],
            0,
            2,
            0.05,
            [0.0; 3],
            &t
        ))
        .contains("zero-size grid"));
        assert!(e(OccupancyMap::from_occupancy_grid(
            &ok, 3, 2, 0.0, [0.0; 3], &t
        ))
        .contains("resolution"));
        assert!(e(OccupancyMap::from_occupancy_grid(
            &ok,
            3,
            2,
            0.05,
            [f64::NAN, 0.0, 0.0],
            &t
        ))
        .contains("origin"));
        let bad = GridThresholds {
            occupied_thresh: 0.2,
            free_thresh: 0.3,
        };
        assert!(e(OccupancyMap::from_occupancy_grid(
            &ok, 3, 2, 0.05, [0.0; 3], &bad
        ))
        .contains("free_thresh"));
    }
}
