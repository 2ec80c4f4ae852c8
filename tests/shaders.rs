//! The WGSL kernels parse and validate with naga (no GPU needed), and their parameter block matches the
//! host's: a broken shader fails here even on a machine without an adapter.

fn validate(name: &str) -> naga::Module {
    let path = format!("{}/shaders/{name}", env!("CARGO_MANIFEST_DIR"));
    let src = std::fs::read_to_string(&path).unwrap();
    let module =
        naga::front::wgsl::parse_str(&src).unwrap_or_else(|e| panic!("{}", e.emit_to_string(&src)));
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::empty(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(&src)));
    module
}

fn params_size(m: &naga::Module) -> u32 {
    let (_, ty) = m
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some("Params"))
        .expect("struct Params");
    match ty.inner {
        naga::TypeInner::Struct { span, .. } => span,
        _ => panic!("Params is not a struct"),
    }
}

#[test]
fn kernels_validate_and_share_the_parameter_layout() {
    let classify = validate("classify.wgsl");
    let corners = validate("ogm_corners.wgsl");
    assert_eq!(params_size(&classify), 64);
    assert_eq!(params_size(&corners), 64);
    let entries = |m: &naga::Module| {
        m.entry_points
            .iter()
            .map(|e| e.name.clone())
            .collect::<Vec<_>>()
    };
    assert_eq!(entries(&classify), ["classify"]);
    assert_eq!(entries(&corners), ["count", "write"]);
}

#[test]
fn every_kernel_has_a_cpu_twin_of_the_same_name() {
    let root = env!("CARGO_MANIFEST_DIR");
    for e in std::fs::read_dir(format!("{root}/shaders")).unwrap() {
        let name = e.unwrap().file_name().into_string().unwrap();
        let stem = name
            .strip_suffix(".wgsl")
            .expect("only .wgsl files in shaders/");
        let twin = format!("{root}/src/cpu/{stem}.rs");
        assert!(
            std::path::Path::new(&twin).is_file(),
            "{name} has no CPU twin at {twin}"
        );
    }
}
