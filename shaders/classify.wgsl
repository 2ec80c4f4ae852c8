// Classification kernel: pixel values -> cell states, four pixels a word.
// CPU twin: src/cpu/classify.rs. The table is computed once in Rust (ClassTable) and uploaded; this kernel
// only indexes it. States: 0 free, 1 unknown, 2 occupied (CellState's representation).

struct Params {
    buf_w: u32,
    buf_h: u32,
    stride: u32, // words per row: ceil(buf_w / 4)
    words: u32,  // stride * buf_h
    core_x0: u32,
    core_y0: u32,
    core_x1: u32,
    core_y1: u32,
    origin_x: u32,
    origin_y: u32,
    unknown_as_occupied: u32,
    groups_x: u32, // workgroups per row of the 2D dispatch
    out_start: u32,
    out_end: u32,
    active_len: u32,
    _pad: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> class_table: array<u32, 256>;
@group(0) @binding(2) var<storage, read> pixels: array<u32>;
@group(0) @binding(3) var<storage, read_write> states: array<u32>;

@compute @workgroup_size(256)
fn classify(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let i = (wg.y * params.groups_x + wg.x) * 256u + li;
    if i >= params.words {
        return;
    }
    let p = pixels[i];
    states[i] = class_table[p & 0xffu]
        | (class_table[(p >> 8u) & 0xffu] << 8u)
        | (class_table[(p >> 16u) & 0xffu] << 16u)
        | (class_table[p >> 24u] << 24u);
}
