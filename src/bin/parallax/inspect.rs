//! `parallax inspect FILE.glb|FILE.gltf`: what a glTF artefact holds once loaded and validated.

use std::path::PathBuf;

use parallax::artefact::{AlphaMode, Artefact, LoadOptions};
use parallax::trace::Trace;

use crate::common::CommonArgs;

/// Arguments of `parallax inspect`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The glTF 2.0 file (`.gltf` or `.glb`).
    file: PathBuf,
    #[command(flatten)]
    common: CommonArgs,
}

/// Loads the file and prints its primitives, triangle counts, materials, textures, extensions,
/// bounds and warnings. A broken file fails with the loader's message.
pub fn run(args: Args) -> parallax::Result<()> {
    let mut trace = Trace::new();
    let artefact = trace.time("artefact.load", "inspect loads the file", |_| {
        Artefact::from_path(&args.file, &LoadOptions::default())
    })?;
    let a = &artefact;
    println!("{}", args.file.display());
    println!(
        "  {} primitives, {} triangles, {} vertices",
        a.primitives.len(),
        a.triangle_count(),
        a.vertex_count()
    );
    let b = a.bounds;
    println!(
        "  bounds: min ({:.6}, {:.6}, {:.6}) max ({:.6}, {:.6}, {:.6}) size ({:.6}, {:.6}, {:.6})",
        b.min.x,
        b.min.y,
        b.min.z,
        b.max.x,
        b.max.y,
        b.max.z,
        b.size().x,
        b.size().y,
        b.size().z
    );
    println!("meshes:");
    for p in &a.primitives {
        let mut attrs = vec!["POSITION", "NORMAL"];
        if p.tangents.is_some() {
            attrs.push("TANGENT");
        }
        if p.uv0.is_some() {
            attrs.push("UV0");
        }
        if p.uv1.is_some() {
            attrs.push("UV1");
        }
        if p.colors.is_some() {
            attrs.push("COLOR_0");
        }
        println!(
            "  mesh {}{} primitive {} at node {}: {} triangles, {} vertices, material {} [{}]",
            p.mesh,
            p.mesh_name
                .as_deref()
                .map(|n| format!(" '{n}'"))
                .unwrap_or_default(),
            p.primitive,
            p.node,
            p.triangle_count(),
            p.positions.len(),
            p.material,
            attrs.join(" ")
        );
    }
    println!("materials:");
    for (i, m) in a.materials.iter().enumerate() {
        let alpha = match m.alpha_mode {
            AlphaMode::Opaque => "OPAQUE".to_string(),
            AlphaMode::Mask { cutoff } => format!("MASK {cutoff}"),
            AlphaMode::Blend => "BLEND".to_string(),
        };
        let c = m.base_color_factor;
        println!(
            "  {i} {}: base ({:.3}, {:.3}, {:.3}, {:.3}) metallic {:.3} roughness {:.3} \
             emissive ({:.3}, {:.3}, {:.3})×{} alpha {alpha}{}",
            m.name.as_deref().unwrap_or("(unnamed)"),
            c.x,
            c.y,
            c.z,
            c.w,
            m.metallic_factor,
            m.roughness_factor,
            m.emissive_factor.x,
            m.emissive_factor.y,
            m.emissive_factor.z,
            m.emissive_strength,
            if m.double_sided { " double-sided" } else { "" }
        );
        for (slot, t) in m.texture_slots() {
            println!(
                "      {slot} texture {} (TEXCOORD_{}{})",
                t.texture,
                t.tex_coord,
                if t.transform.is_some() {
                    ", transformed"
                } else {
                    ""
                }
            );
        }
    }
    println!("textures:");
    for (i, t) in a.textures.iter().enumerate() {
        println!(
            "  {i} '{}' {}x{} wrap {:?}/{:?} filter mag {:?} min {:?} mip {:?}",
            t.image.name,
            t.image.width,
            t.image.height,
            t.sampler.wrap_u,
            t.sampler.wrap_v,
            t.sampler.mag_filter,
            t.sampler.min_filter,
            t.sampler.mipmap_filter
        );
    }
    println!(
        "extensions: used [{}], required [{}]",
        a.extensions_used.join(", "),
        a.extensions_required.join(", ")
    );
    println!("warnings: {}", a.warnings.len());
    for w in &a.warnings {
        println!("  {w}");
    }
    args.common.finish(&trace)
}
