//! The WGSL kernels parse and validate with naga (no GPU needed), exactly as the GPU backend assembles
//! them, and their parameter blocks match the host's: a broken shader fails here even without an adapter.

/// Parses and validates a kernel exactly as the GPU backend assembles it.
fn validate_kernel(kernel: &str, native_int64: bool) -> naga::Module {
    let src = ogm_corners::backend::gpu::shader_source(kernel, native_int64).expect("known kernel");
    let module = naga::front::wgsl::parse_str(&src)
        .unwrap_or_else(|e| panic!("{kernel}: {}", e.emit_to_string(&src)));
    let caps = if native_int64 {
        naga::valid::Capabilities::SHADER_INT64
    } else {
        naga::valid::Capabilities::empty()
    };
    naga::valid::Validator::new(naga::valid::ValidationFlags::all(), caps)
        .validate(&module)
        .unwrap_or_else(|e| panic!("{kernel}: {}", e.emit_to_string(&src)));
    module
}

fn struct_size(m: &naga::Module, name: &str) -> u32 {
    let (_, ty) = m
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("struct {name}"));
    match ty.inner {
        naga::TypeInner::Struct { span, .. } => span,
        _ => panic!("{name} is not a struct"),
    }
}

fn entries(m: &naga::Module) -> Vec<String> {
    m.entry_points.iter().map(|e| e.name.clone()).collect()
}

#[test]
fn ogm_kernels_validate_and_their_parameters_match_the_host() {
    let corners = validate_kernel("ogm_corners", false);
    // src/backend/gpu/ogm.rs OgmParams: 24 four-byte fields.
    assert_eq!(struct_size(&corners, "Params"), 96);
    assert_eq!(entries(&corners), ["detect", "scatter", "finish"]);
    let scan = validate_kernel("scan", false);
    // src/backend/gpu/scan.rs ScanParams: 4 four-byte fields.
    assert_eq!(struct_size(&scan, "Params"), 16);
    assert_eq!(entries(&scan), ["scan_blocks", "scan_add"]);
}

#[test]
fn the_selection_kernel_validates_and_its_parameters_match_the_host() {
    let m = validate_kernel("select_maxima", false);
    assert_eq!(entries(&m), ["count", "reduce_max", "scatter"]);
    // src/backend/gpu/select.rs SelParams: 16 four-byte fields.
    assert_eq!(struct_size(&m, "Params"), 64);
}

#[test]
fn the_coarsening_kernel_validates_and_its_parameters_match_the_host() {
    let m = validate_kernel("coarsen", false);
    assert_eq!(entries(&m), ["coarsen"]);
    // src/backend/gpu/coarsen.rs CParams: 28 four-byte fields.
    assert_eq!(struct_size(&m, "Params"), 112);
}

#[test]
fn the_scoring_kernel_validates_and_its_parameters_match_the_host() {
    let m = validate_kernel("merge_score", false);
    assert_eq!(entries(&m), ["merge_score"]);
    // src/backend/gpu/merge_score.rs SParams: 8 four-byte fields.
    assert_eq!(struct_size(&m, "Params"), 32);
}

#[test]
fn baseline_kernels_validate_with_both_int64_libraries() {
    for k in [
        "gaussian_blur",
        "structure_tensor",
        "harris",
        "shi_tomasi",
        "trajkovic",
    ] {
        for native in [false, true] {
            let m = validate_kernel(k, native);
            assert_eq!(entries(&m), [k]);
            assert_eq!(struct_size(&m, "BParams"), 80, "{k}");
        }
    }
}

#[test]
fn every_kernel_has_a_cpu_twin_of_the_same_name() {
    let root = env!("CARGO_MANIFEST_DIR");
    let mut kernels = 0;
    for e in std::fs::read_dir(format!("{root}/shaders")).unwrap() {
        let e = e.unwrap();
        if e.file_type().unwrap().is_dir() {
            continue; // shaders/lib: libraries prepended to kernels, not kernels
        }
        let name = e.file_name().into_string().unwrap();
        let stem = name
            .strip_suffix(".wgsl")
            .expect("only .wgsl files in shaders/");
        let twin = format!("{root}/src/backend/reference/{stem}.rs");
        assert!(
            std::path::Path::new(&twin).is_file(),
            "{name} has no CPU twin at {twin}"
        );
        assert!(
            ogm_corners::backend::gpu::shader_source(stem, false).is_some(),
            "{name} is not built"
        );
        kernels += 1;
    }
    assert_eq!(kernels, 10);
}
