//! CPU twin of the corner kernel: the 8-neighbour code of every free pixel, looked up in the rule table.

use crate::backend::rules::{RuleTable, NEIGHBOUR_OFFSETS};
use crate::backend::Keypoint;
use crate::map::states::CellState;

/// Whether a neighbour in state `s` sets its bit in the code.
#[inline]
pub fn blocks(s: CellState, unknown_as_occupied: bool) -> bool {
    match s {
        CellState::Occupied => true,
        CellState::Unknown => unknown_as_occupied,
        CellState::Free => false,
    }
}

/// The 8-neighbour code of pixel (x, y); neighbours outside the map count as not occupied.
pub fn neighbour_code(
    states: &[CellState],
    width: u32,
    height: u32,
    x: u32,
    y: u32,
    unknown_as_occupied: bool,
) -> u8 {
    let mut code = 0u8;
    for (bit, (dx, dy)) in NEIGHBOUR_OFFSETS.iter().enumerate() {
        let nx = x as i64 + *dx as i64;
        let ny = y as i64 + *dy as i64;
        if nx < 0 || ny < 0 || nx >= width as i64 || ny >= height as i64 {
            continue;
        }
        let s = states[ny as usize * width as usize + nx as usize];
        if blocks(s, unknown_as_occupied) {
            code |= 1 << bit;
        }
    }
    code
}

/// The code of a pixel at least one pixel away from every edge, at row-major index `i`: no bounds checks.
#[inline]
fn interior_code(states: &[CellState], width: usize, i: usize, unknown_as_occupied: bool) -> u8 {
    let mut code = 0u8;
    for (bit, (dx, dy)) in NEIGHBOUR_OFFSETS.iter().enumerate() {
        let j = (i as isize + *dy as isize * width as isize + *dx as isize) as usize;
        code |= u8::from(blocks(states[j], unknown_as_occupied)) << bit;
    }
    code
}

/// Every free pixel whose neighbour code the table accepts, in (y, x) order.
pub fn ogm_corners(
    states: &[CellState],
    width: u32,
    height: u32,
    rules: &RuleTable,
    unknown_as_occupied: bool,
) -> Vec<Keypoint> {
    debug_assert_eq!(states.len(), width as usize * height as usize);
    let mut out = Vec::new();
    for y in 0..height {
        for x in 0..width {
            let i = y as usize * width as usize + x as usize;
            if states[i] != CellState::Free {
                continue;
            }
            let code = if x > 0 && y > 0 && x + 1 < width && y + 1 < height {
                interior_code(states, width as usize, i, unknown_as_occupied)
            } else {
                neighbour_code(states, width, height, x, y, unknown_as_occupied)
            };
            if let Some(rule) = rules.rule(code) {
                out.push(Keypoint::ogm(x, y, rule, code));
            }
        }
    }
    out
}
