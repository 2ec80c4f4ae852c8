// Exclusive prefix sum of u32 counts on the device. CPU twin: src/cpu/scan.rs.
//
// A level of n entries at data[off..off + n] is scanned in blocks of 1024 (256 invocations of four):
// `scan_blocks` turns each block into its exclusive prefix and writes the block's total to the next level,
// data[next + block]; the host scans that level the same way (recursively, in the same submission), then
// `scan_add` adds each block's prefix back. Every position depends only on the counts, so the result is
// deterministic.

struct Params {
    n: u32,
    off: u32,
    next: u32,
    groups_x: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> data: array<u32>;

var<workgroup> sums: array<u32, 256>;

@compute @workgroup_size(256)
fn scan_blocks(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let block = wg.y * params.groups_x + wg.x;
    let first = block * 1024u + li * 4u;
    var v = vec4<u32>(0u);
    for (var k = 0u; k < 4u; k++) {
        if first + k < params.n {
            v[k] = data[params.off + first + k];
        }
    }
    let own = v.x + v.y + v.z + v.w;
    // Inclusive scan of the 256 sums (Hillis-Steele).
    sums[li] = own;
    workgroupBarrier();
    for (var d = 1u; d < 256u; d <<= 1u) {
        var add = 0u;
        if li >= d {
            add = sums[li - d];
        }
        workgroupBarrier();
        sums[li] += add;
        workgroupBarrier();
    }
    var acc = sums[li] - own;
    for (var k = 0u; k < 4u; k++) {
        if first + k < params.n {
            data[params.off + first + k] = acc;
        }
        acc += v[k];
    }
    if li == 255u && block * 1024u < params.n {
        data[params.next + block] = sums[255];
    }
}

@compute @workgroup_size(256)
fn scan_add(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let block = wg.y * params.groups_x + wg.x;
    let add = data[params.next + block];
    for (var k = 0u; k < 4u; k++) {
        let i = block * 1024u + li * 4u + k;
        if i < params.n {
            data[params.off + i] += add;
        }
    }
}
