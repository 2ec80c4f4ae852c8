// How ogm_corners.wgsl reads its pixels when every run of 32 starts 16-byte aligned in the binding (staged
// bands, whose rows are padded to whole runs; maps in device buffers with such an offset and pitch): two
// 16-byte loads a run. Prepended to ogm_corners.wgsl; shaders/lib/ogm_fetch_bytes.wgsl is the other form.

@group(0) @binding(2) var<storage, read> pixels: array<vec4<u32>>;

// The 32 pixels from byte `at` of the binding (a multiple of 16), four a word, pixel k at byte k % 4.
fn run_at(at: u32) -> array<u32, 8> {
    let a = pixels[at >> 4u];
    let b = pixels[(at >> 4u) + 1u];
    return array<u32, 8>(a.x, a.y, a.z, a.w, b.x, b.y, b.z, b.w);
}

// The pixel at byte `at` of the binding, in bits 0..7.
fn byte_at(at: u32) -> u32 {
    let w = at >> 2u;
    return (pixels[w >> 2u][w & 3u] >> ((at & 3u) * 8u)) & 0xffu;
}
