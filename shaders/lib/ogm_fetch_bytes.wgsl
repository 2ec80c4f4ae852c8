// How ogm_corners.wgsl reads its pixels from a map at any byte offset and row pitch (a map in a caller's
// device buffer): nine 4-byte loads a run of 32, funnel-shifted when the run does not start on a word.
// Prepended to ogm_corners.wgsl; shaders/lib/ogm_fetch_runs.wgsl is the aligned form.

@group(0) @binding(2) var<storage, read> pixels: array<u32>;

// The 32 pixels from byte `at` of the binding, four a word, pixel k at byte k % 4.
fn run_at(at: u32) -> array<u32, 8> {
    let w = at >> 2u;
    let s = (at & 3u) * 8u;
    var out: array<u32, 8>;
    var lo = pixels[w];
    for (var k = 0u; k < 8u; k++) {
        let hi = pixels[w + k + 1u];
        // WGSL takes a shift modulo 32, so a run that starts on a word takes its words whole.
        out[k] = select((lo >> s) | (hi << (32u - s)), lo, s == 0u);
        lo = hi;
    }
    return out;
}

// The pixel at byte `at` of the binding, in bits 0..7.
fn byte_at(at: u32) -> u32 {
    return (pixels[at >> 2u] >> ((at & 3u) * 8u)) & 0xffu;
}
