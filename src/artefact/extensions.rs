//! Which glTF extensions the loader understands, and what happens to the others: a required one
//! it cannot honour is an `Unsupported` error naming it (drawing without it would be wrong, e.g.
//! compressed geometry read as garbage); an optional one is ignored with a warning (the file
//! promises a correct fallback).

use crate::error::{Error, Result};

/// Extensions whose data the loader applies.
pub const SUPPORTED_EXTENSIONS: &[&str] = &[
    "KHR_materials_emissive_strength",
    "KHR_texture_transform",
    // Integer and normalized vertex attributes are read like any accessor.
    "KHR_mesh_quantization",
];

/// Why a known-but-unsupported extension matters, for the error message.
fn reason(name: &str) -> &'static str {
    match name {
        "KHR_draco_mesh_compression" => "Draco-compressed geometry cannot be decoded",
        "EXT_meshopt_compression" => "meshoptimizer-compressed buffers cannot be decoded",
        "KHR_texture_basisu" => "KTX2/Basis Universal textures cannot be decoded",
        "EXT_texture_webp" => "WebP textures cannot be decoded",
        "MSFT_texture_dds" => "DDS textures cannot be decoded",
        "KHR_mesh_gpu_instancing" | "EXT_mesh_gpu_instancing" => {
            "GPU instancing of nodes is not applied"
        }
        _ => "this loader does not implement it",
    }
}

/// Checks the asset's `extensionsRequired` and `extensionsUsed`.
///
/// Returns the warnings for optional extensions that will be ignored.
///
/// # Errors
/// `Unsupported` naming the first required extension this loader does not implement.
pub(crate) fn check(required: &[String], used: &[String]) -> Result<Vec<String>> {
    if let Some(name) = required
        .iter()
        .find(|r| !SUPPORTED_EXTENSIONS.contains(&r.as_str()))
    {
        return Err(Error::Unsupported(format!(
            "the asset requires the glTF extension {name}, which is not supported ({})",
            reason(name)
        )));
    }
    let mut warnings = Vec::new();
    for name in used {
        if !SUPPORTED_EXTENSIONS.contains(&name.as_str()) {
            warnings.push(format!(
                "optional glTF extension {name} is ignored ({}); the asset's fallback is drawn",
                reason(name)
            ));
        }
    }
    Ok(warnings)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(names: &[&str]) -> Vec<String> {
        names.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn required_unsupported_extensions_are_named() {
        for name in [
            "KHR_draco_mesh_compression",
            "EXT_meshopt_compression",
            "KHR_texture_basisu",
            "VENDOR_something_new",
        ] {
            let e = check(&v(&[name]), &v(&[name])).unwrap_err();
            assert!(matches!(e, Error::Unsupported(_)), "{e}");
            assert!(e.to_string().contains(name), "{e}");
        }
    }

    #[test]
    fn supported_required_extensions_pass_and_optional_ones_warn() {
        let w = check(
            &v(&["KHR_texture_transform"]),
            &v(&[
                "KHR_texture_transform",
                "KHR_materials_clearcoat",
                "KHR_materials_emissive_strength",
            ]),
        )
        .unwrap();
        assert_eq!(w.len(), 1);
        assert!(w[0].contains("KHR_materials_clearcoat"));
    }
}
