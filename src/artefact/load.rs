//! The loading sequence: parse and validate the JSON, check extensions, flatten the nodes, check
//! the claimed sizes against the caps, and only then read buffers, materials and primitives.

use std::collections::HashMap;
use std::path::Path;

use gltf::mesh::Semantic;

use super::buffers::Buffers;
use super::limits::{mul, MemoryBudget};
use super::material::{Material, MaterialBuilder};
use super::mesh::{self, Context, MAX_VERTEX_BYTES};
use super::{extensions, Aabb, Artefact, LoadOptions};
use crate::error::{Error, Result};

/// How many validation problems an error message lists before "and N more".
const LISTED_PROBLEMS: usize = 5;

pub(crate) fn load(
    bytes: &[u8],
    base: Option<&Path>,
    source: &str,
    options: &LoadOptions,
) -> Result<Artefact> {
    let limits = &options.limits;
    let mut budget = MemoryBudget::new(limits);
    budget.reserve(&format!("{source} (file bytes)"), bytes.len() as u64)?;
    let mut warnings = Vec::new();
    let kind = if bytes.starts_with(b"glTF") {
        "GLB"
    } else {
        "glTF JSON"
    };

    let gltf::Gltf { document, blob } = gltf::Gltf::from_slice_without_validation(bytes)
        .map_err(|e| Error::format(format!("{source}: invalid {kind}: {e}")))?;
    let mut json = document.into_json();

    let version = json.asset.version.as_str();
    if !version.starts_with("2.") {
        return Err(Error::Unsupported(format!(
            "{source}: glTF version '{version}'; only glTF 2.x is supported"
        )));
    }
    let extensions_used = json.extensions_used.clone();
    let extensions_required = json.extensions_required.clone();
    warnings.extend(extensions::check(&extensions_required, &extensions_used)?);
    // Validation below only knows the `gltf` crate's extension list; ours is checked above.
    json.extensions_required.clear();
    if let Some(scene) = json.scene {
        if scene.value() >= json.scenes.len() {
            warnings.push(format!(
                "default scene {} does not exist ({} scenes); ignored",
                scene.value(),
                json.scenes.len()
            ));
            json.scene = None;
        }
    }
    let doc = gltf::Document::from_json(json).map_err(|e| match e {
        gltf::Error::Validation(problems) => {
            let listed: Vec<String> = problems
                .iter()
                .take(LISTED_PROBLEMS)
                .map(|(path, err)| format!("{path}: {err}"))
                .collect();
            let more = problems.len().saturating_sub(LISTED_PROBLEMS);
            Error::format(format!(
                "{source}: invalid glTF: {}{}",
                listed.join("; "),
                if more > 0 {
                    format!(" (and {more} more)")
                } else {
                    String::new()
                }
            ))
        }
        other => Error::format(format!("{source}: invalid glTF: {other}")),
    })?;

    // Plan: what will be drawn, and whether it fits, before any buffer is read.
    let instances = mesh::flatten(&doc, limits, &mut warnings)?;
    let mut drawn = Vec::new();
    let (mut vertices, mut triangles) = (0u64, 0u64);
    for instance in &instances {
        for primitive in instance.mesh.primitives() {
            let what = primitive_label(instance, &primitive);
            let Some(claim) = mesh::claim(&primitive, &what, &mut warnings)? else {
                continue;
            };
            vertices = vertices.saturating_add(claim.vertices);
            triangles = triangles.saturating_add(claim.triangles);
            if vertices > limits.max_vertices {
                return Err(Error::TooLarge(format!(
                    "{source}: {what} brings the vertex count to {vertices}, over the cap of {} \
                     (LoadLimits::max_vertices)",
                    limits.max_vertices
                )));
            }
            if triangles > limits.max_triangles {
                return Err(Error::TooLarge(format!(
                    "{source}: {what} brings the triangle count to {triangles}, over the cap of \
                     {} (LoadLimits::max_triangles)",
                    limits.max_triangles
                )));
            }
            drawn.push((instance, primitive, what));
        }
    }
    let output_bytes = mul(vertices, MAX_VERTEX_BYTES, "vertex data")?.saturating_add(mul(
        triangles,
        12,
        "index data",
    )?);
    budget.reserve("the flattened vertex and index data", output_bytes)?;

    let buffers = Buffers::load(&doc, blob, base, &mut budget)?;
    let mut builder = MaterialBuilder::new(&buffers, base, limits);
    let mut materials: Vec<Material> = Vec::new();
    let mut material_map: HashMap<Option<usize>, usize> = HashMap::new();
    let mut variant_map: HashMap<(usize, u32), usize> = HashMap::new();
    let ctx = Context {
        buffers: &buffers,
        limits,
    };
    let mut primitives = Vec::with_capacity(drawn.len());
    for (instance, primitive, what) in drawn {
        let gltf_material = primitive.material();
        let mut index = match material_map.get(&gltf_material.index()) {
            Some(&i) => i,
            None => {
                let m = builder.convert(&gltf_material, &mut warnings, &mut budget)?;
                materials.push(m);
                material_map.insert(gltf_material.index(), materials.len() - 1);
                materials.len() - 1
            }
        };
        // A texture that reads a coordinate set the primitive lacks cannot be drawn: that
        // primitive gets a copy of the material without it.
        let sets: Vec<u32> = materials[index]
            .texture_slots()
            .iter()
            .map(|(_, t)| t.tex_coord)
            .collect();
        for set in sets {
            if primitive.get(&Semantic::TexCoords(set)).is_some() && set <= 1 {
                continue;
            }
            if materials[index]
                .texture_slots()
                .iter()
                .all(|(_, t)| t.tex_coord != set)
            {
                continue;
            }
            let names: Vec<&str> = materials[index]
                .texture_slots()
                .iter()
                .filter(|(_, t)| t.tex_coord == set)
                .map(|(n, _)| *n)
                .collect();
            warnings.push(format!(
                "{what}: its material's {} texture reads TEXCOORD_{set}, which the primitive \
                 lacks (or which is not supported past TEXCOORD_1); drawn without it",
                names.join(", ")
            ));
            index = match variant_map.get(&(index, set)) {
                Some(&v) => v,
                None => {
                    let mut m = materials[index].without_tex_coord(set);
                    m.name = Some(format!(
                        "{} (without TEXCOORD_{set} textures)",
                        m.name.as_deref().unwrap_or("material")
                    ));
                    materials.push(m);
                    variant_map.insert((index, set), materials.len() - 1);
                    materials.len() - 1
                }
            };
        }
        let wants_tangents = materials[index].normal_texture.map(|t| t.tex_coord);
        primitives.push(mesh::build(
            &ctx,
            instance,
            &primitive,
            &what,
            index,
            wants_tangents,
            &mut warnings,
            &mut budget,
        )?);
    }
    let textures = builder.textures;
    let bounds = primitives
        .iter()
        .map(|p| p.bounds)
        .reduce(|a, b| a.union(&b))
        .unwrap_or(Aabb::ZERO);
    if primitives.iter().all(|p| p.indices.is_empty()) {
        warnings.push(format!("{source}: the asset holds no drawable triangles"));
    }
    Ok(Artefact {
        source: source.to_string(),
        primitives,
        materials,
        textures,
        extensions_used,
        extensions_required,
        warnings,
        bounds,
    })
}

fn primitive_label(instance: &mesh::MeshInstance, primitive: &gltf::Primitive) -> String {
    let mesh = match instance.mesh.name() {
        Some(n) => format!("mesh {} ('{n}')", instance.mesh.index()),
        None => format!("mesh {}", instance.mesh.index()),
    };
    format!(
        "{mesh} primitive {} (node {})",
        primitive.index(),
        instance.node.index()
    )
}
