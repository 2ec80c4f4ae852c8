// Coarsening kernel of the robust detector: the map sampled on a rotated grid by nearest neighbour, each
// scale x scale box of samples becoming one coarse cell (0 occupied, 254 free, 205 unknown), at every
// grid phase: the cells of phase (a, b) start at samples (u scale - a, v scale - b) and form tile (a, b)
// of the output, each tile followed by a gutter column and row of unknown cells.
// CPU twin: src/cpu/coarsen.rs. The sample positions are the integer sums of src/grid.rs (i32, wrapping as
// in Rust, arithmetic shifts; ties towards the map's centre), the class table and the cell thresholds come
// from Rust as data, so every coarse cell is bit-identical to the CPU's. Each invocation writes one word:
// four cells of a row.

struct Params {
    cos: i32,
    sin: i32,
    ox: i32,
    oy: i32,
    map_w: u32,
    map_h: u32,
    // The uploaded rectangle of the map: origin, size and words per row.
    band_x0: u32,
    band_y0: u32,
    band_w: u32,
    band_h: u32,
    band_stride: u32,
    scale: u32,
    // The tile of coarse cells this dispatch writes: first cell, size, output words per row.
    cell_u0: u32,
    cell_v0: u32,
    tile_w: u32,
    tile_h: u32,
    out_stride: u32,
    occ_min: u32,
    free_min: u32,
    groups_x: u32,
    frac_bits: u32,
    // The map's centre (fixed point): a sample half-way between two pixels reads the one nearer it.
    cx: i32,
    cy: i32,
    // Cells of one phase's tile, a row and a column (the gutter follows).
    mosaic_w: u32,
    mosaic_h: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> class_table: array<u32, 256>;
@group(0) @binding(2) var<storage, read> pixels: array<u32>;
@group(0) @binding(3) var<storage, read_write> cells: array<u32>;

const FREE_STATE: u32 = 0u;
const OCCUPIED_STATE: u32 = 2u;
const UNKNOWN_STATE: u32 = 1u;

// The state of sample (p, q): its nearest map pixel's, unknown outside the map.
// The pixel nearest fixed-point coordinate v, ties towards `centre` (grid::nearest).
fn nearest(v: i32, centre: i32) -> i32 {
    let half = 1 << (params.frac_bits - 1u);
    let one = 1 << params.frac_bits;
    let up = (v + half) >> params.frac_bits;
    return up - select(0, 1, (v & (one - 1)) == half && v > centre);
}

fn sample_state(p: i32, q: i32) -> u32 {
    let x = nearest(params.ox + p * params.cos - q * params.sin, params.cx);
    let y = nearest(params.oy + p * params.sin + q * params.cos, params.cy);
    if x < 0 || y < 0 || u32(x) >= params.map_w || u32(y) >= params.map_h {
        return UNKNOWN_STATE;
    }
    let bx = u32(x) - params.band_x0;
    let by = u32(y) - params.band_y0;
    // The host uploads every row and column the tile's samples reach; this never trips.
    if bx >= params.band_w || by >= params.band_h {
        return UNKNOWN_STATE;
    }
    let word = pixels[by * params.band_stride + bx / 4u];
    return class_table[(word >> ((bx % 4u) * 8u)) & 0xffu];
}

fn cell_value(x: u32, y: u32) -> u32 {
    let s = params.scale;
    let u = x % (params.mosaic_w + 1u);
    let v = y % (params.mosaic_h + 1u);
    if u == params.mosaic_w || v == params.mosaic_h {
        return 205u; // the gutter between phases
    }
    let p0 = i32(u * s) - i32(x / (params.mosaic_w + 1u));
    let q0 = i32(v * s) - i32(y / (params.mosaic_h + 1u));
    var occupied = 0u;
    var free = 0u;
    for (var j = 0; j < i32(s); j++) {
        for (var i = 0; i < i32(s); i++) {
            let st = sample_state(p0 + i, q0 + j);
            occupied += select(0u, 1u, st == OCCUPIED_STATE);
            free += select(0u, 1u, st == FREE_STATE);
        }
    }
    if occupied >= params.occ_min {
        return 0u;
    }
    if free >= params.free_min {
        return 254u;
    }
    return 205u;
}

@compute @workgroup_size(64)
fn coarsen(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let i = (wg.y * params.groups_x + wg.x) * 64u + li;
    if i >= params.out_stride * params.tile_h {
        return;
    }
    let row = i / params.out_stride;
    let col = (i % params.out_stride) * 4u;
    var word = 0u;
    for (var k = 0u; k < 4u; k++) {
        if col + k < params.tile_w {
            word |= cell_value(params.cell_u0 + col + k, params.cell_v0 + row) << (8u * k);
        }
    }
    cells[i] = word;
}
