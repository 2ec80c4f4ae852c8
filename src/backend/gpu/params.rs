//! The kernels' parameter blocks, one source for each: [`kernel_params!`] declares the Rust struct and
//! records its layout (each field's name, byte offset and type), which the tests below check field by field
//! against the WGSL struct of the same block through naga's reflection of the shader as the GPU receives it.

/// Declares a kernel's parameter block (a `#[repr(C)]` struct of 4-byte fields laid out as its WGSL
/// twin) and, in tests, `LAYOUT`: each field's name, byte offset and Rust type.
macro_rules! kernel_params {
    ($(#[$meta:meta])* $vis:vis struct $name:ident {
        $($(#[$fmeta:meta])* $fvis:vis $field:ident : $ty:ty),* $(,)?
    }) => {
        $(#[$meta])*
        $vis struct $name {
            $($(#[$fmeta])* $fvis $field: $ty),*
        }

        #[cfg(test)]
        impl $name {
            /// Each field's name, byte offset and Rust type, for the check against the WGSL struct.
            pub(crate) const LAYOUT: &'static [(&'static str, usize, &'static str)] = &[
                $((stringify!($field), ::std::mem::offset_of!($name, $field), stringify!($ty))),*
            ];
        }
    };
}
pub(super) use kernel_params;

#[cfg(test)]
mod tests {
    use super::super::{
        baselines::BParams, coarsen::CParams, merge_score::SParams, ogm::OgmParams,
        ogm_shader_source, scan::ScanParams, select::SelParams, shader_source,
    };

    /// The members of WGSL struct `name` in `src`: name, byte offset and scalar type (`u32`, `i32`,
    /// `f32`).
    fn wgsl_members(src: &str, name: &str) -> Vec<(String, usize, String)> {
        let module = naga::front::wgsl::parse_str(src).expect("the kernel parses");
        let (_, ty) = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("no struct {name}"));
        let naga::TypeInner::Struct { members, .. } = &ty.inner else {
            panic!("{name} is not a struct");
        };
        members
            .iter()
            .map(|m| {
                let scalar = match &module.types[m.ty].inner {
                    naga::TypeInner::Scalar(s) => match (s.kind, s.width) {
                        (naga::ScalarKind::Uint, 4) => "u32",
                        (naga::ScalarKind::Sint, 4) => "i32",
                        (naga::ScalarKind::Float, 4) => "f32",
                        other => panic!("{name}: unexpected scalar {other:?}"),
                    },
                    other => panic!("{name}: member of type {other:?}, not a 4-byte scalar"),
                };
                let member = m.name.clone().unwrap_or_default();
                (member, m.offset as usize, scalar.to_string())
            })
            .collect()
    }

    /// The Rust layout with arrays of padding (`[u32; N]`) spread into their N words.
    fn rust_members(layout: &[(&str, usize, &str)]) -> Vec<(String, usize, String)> {
        let mut out = Vec::new();
        for &(name, offset, ty) in layout {
            let ty = ty.replace(' ', "");
            match ty.strip_prefix('[').and_then(|t| t.strip_suffix(']')) {
                Some(array) => {
                    let (scalar, n) = array.split_once(';').expect("[T; N]");
                    for k in 0..n.parse::<usize>().expect("a length") {
                        out.push((name.to_string(), offset + 4 * k, scalar.to_string()));
                    }
                }
                None => out.push((name.to_string(), offset, ty)),
            }
        }
        out
    }

    /// Field by field: the same names (padding words may be named apart), offsets and types.
    fn check(what: &str, src: &str, wgsl: &str, layout: &[(&str, usize, &str)]) {
        let (w, r) = (wgsl_members(src, wgsl), rust_members(layout));
        assert_eq!(w.len(), r.len(), "{what}: WGSL {w:?}, Rust {r:?}");
        for (a, b) in w.iter().zip(&r) {
            let padding = a.0.starts_with("_pad") && b.0.starts_with("_pad");
            assert!(
                (padding || a.0 == b.0) && a.1 == b.1 && a.2 == b.2,
                "{what}: WGSL {a:?}, Rust {b:?}"
            );
        }
    }

    #[test]
    fn every_parameter_block_matches_its_wgsl_field_by_field() {
        let source = |k: &str| shader_source(k, false).expect("a kernel");
        for any in [false, true] {
            check("ogm", &ogm_shader_source(any), "Params", OgmParams::LAYOUT);
        }
        check("scan", &source("scan"), "Params", ScanParams::LAYOUT);
        check(
            "select",
            &source("select_maxima"),
            "Params",
            SelParams::LAYOUT,
        );
        check("coarsen", &source("coarsen"), "Params", CParams::LAYOUT);
        check("score", &source("merge_score"), "Params", SParams::LAYOUT);
        for k in [
            "gaussian_blur",
            "structure_tensor",
            "harris",
            "shi_tomasi",
            "trajkovic",
        ] {
            check(k, &source(k), "BParams", BParams::LAYOUT);
        }
    }

    #[test]
    fn the_check_sees_a_swapped_field() {
        let src = "struct P { a: u32, b: i32, }";
        let layout = [("a", 0, "u32"), ("b", 4, "i32")];
        check("same", src, "P", &layout);
        let swapped = [("b", 0, "i32"), ("a", 4, "u32")];
        let caught = std::panic::catch_unwind(|| check("swapped", src, "P", &swapped));
        assert!(caught.is_err());
    }
}
