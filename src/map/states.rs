//! The three map states and the table from pixel value to state, computed once per set of thresholds so
//! that every backend applies the identical table.

use crate::map::Thresholds;

/// ROS `map_server` value of a free cell.
pub const FREE: u8 = 254;
/// ROS `map_server` value of an unknown cell.
pub const UNKNOWN: u8 = 205;
/// ROS `map_server` value of an occupied cell.
pub const OCCUPIED: u8 = 0;

/// The state of one map cell.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum CellState {
    /// Seen empty by the robot.
    Free = 0,
    /// Never observed.
    Unknown = 1,
    /// Seen as an obstacle.
    Occupied = 2,
}

impl CellState {
    /// The value ROS `map_server` writes for this state ([`OCCUPIED`], [`FREE`], [`UNKNOWN`]).
    pub fn map_server_value(self) -> u8 {
        match self {
            CellState::Occupied => OCCUPIED,
            CellState::Free => FREE,
            CellState::Unknown => UNKNOWN,
        }
    }
}

/// The state of each of the 256 pixel values, from ROS trinary semantics.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ClassTable {
    states: [CellState; 256],
}

impl ClassTable {
    /// Builds the table: p = (255 - v) / 255 (v / 255 when negated); occupied if p > occupied_thresh, free
    /// if p < free_thresh, otherwise unknown. The arithmetic is in f64, as in ROS `map_server`.
    pub fn new(t: &Thresholds) -> Self {
        let mut states = [CellState::Unknown; 256];
        for (v, s) in states.iter_mut().enumerate() {
            let v = v as f64;
            let p = if t.negate {
                v / 255.0
            } else {
                (255.0 - v) / 255.0
            };
            *s = if p > t.occupied_thresh {
                CellState::Occupied
            } else if p < t.free_thresh {
                CellState::Free
            } else {
                CellState::Unknown
            };
        }
        ClassTable { states }
    }

    /// A table given state by state (the robust detector reads its coarse maps so).
    pub fn from_states(states: [CellState; 256]) -> Self {
        ClassTable { states }
    }

    /// The state of pixel value `v`.
    #[inline]
    pub fn state(&self, v: u8) -> CellState {
        self.states[v as usize]
    }

    /// The value ROS `map_server` writes for each pixel value's state (0, 205, 254): the table that draws
    /// an image read with this table as a trinary map.
    pub fn map_server_values(&self) -> [u8; 256] {
        self.states.map(CellState::map_server_value)
    }

    /// All 256 states, indexed by pixel value (for upload to other backends).
    pub fn states(&self) -> &[CellState; 256] {
        &self.states
    }
}

impl Default for ClassTable {
    /// The table for the ROS default thresholds.
    fn default() -> Self {
        ClassTable::new(&Thresholds::default())
    }
}
