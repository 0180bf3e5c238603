//! The loading sequence: parse and validate the JSON, check extensions, flatten the nodes, check
//! the claimed sizes against the caps, and only then read buffers, materials and primitives.

use std::collections::HashMap;
use std::path::Path;

use gltf::mesh::Semantic;

use super::buffers::Buffers;
use super::limits::{mul, MemoryBudget};
use super::material::{Material, MaterialBuilder};
use super::mesh::{self, Context, MAX_VERTEX_BYTES};
use super::{extensions, glb, Aabb, Artefact, LoadOptions};
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
    let (mut json, blob) = parse(bytes, source)?;

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
    check_position_indices(&json)?;
    let mut problems = Vec::new();
    {
        use gltf::json::validation::Validate;
        json.validate(&json, gltf::json::Path::new, &mut |path, err| {
            let path = path();
            if !is_missing_position_bounds(&path, &err) {
                problems.push(format!("{path}: {err}"));
            }
        });
    }
    if !problems.is_empty() {
        let more = problems.len().saturating_sub(LISTED_PROBLEMS);
        problems.truncate(LISTED_PROBLEMS);
        return Err(Error::format(format!(
            "{source}: invalid glTF: {}{}",
            problems.join("; "),
            if more > 0 {
                format!(" (and {more} more)")
            } else {
                String::new()
            }
        )));
    }
    let doc = gltf::Document::from_json_without_validation(json);

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
    let mut builder = MaterialBuilder::new(&doc, &buffers, base, limits);
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

/// The `gltf` crate's validation indexes the POSITION accessor without a bounds check, so a
/// dangling POSITION index must be caught before it runs.
fn check_position_indices(json: &gltf::json::Root) -> Result<()> {
    use gltf::json::validation::Checked;
    for (m, mesh) in json.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let position = Checked::Valid(gltf::json::mesh::Semantic::Positions);
            if let Some(index) = primitive.attributes.get(&position) {
                if index.value() >= json.accessors.len() {
                    return Err(Error::format(format!(
                        "mesh {m} primitive {p}: POSITION refers to accessor {}, but there are \
                         only {} accessors",
                        index.value(),
                        json.accessors.len()
                    )));
                }
            }
        }
    }
    Ok(())
}

/// Splits GLB or reads JSON, and deserialises the glTF root.
fn parse(bytes: &[u8], source: &str) -> Result<(gltf::json::Root, Option<Vec<u8>>)> {
    let (json, blob, kind) = if glb::is_glb(bytes) {
        let g = glb::parse(bytes).map_err(|e| Error::format(format!("{source}: {e}")))?;
        (g.json, g.bin.map(<[u8]>::to_vec), "GLB JSON chunk")
    } else {
        (bytes, None, "glTF JSON")
    };
    match serde_json::from_slice::<gltf::json::Root>(json) {
        Ok(root) => Ok((root, blob)),
        Err(first) => {
            // glTF 2.0 allows a scene without `nodes`; the `gltf` crate requires the field.
            if let Ok(mut value) = serde_json::from_slice::<serde_json::Value>(json) {
                if add_missing_scene_nodes(&mut value) {
                    if let Ok(root) = serde_json::from_value::<gltf::json::Root>(value) {
                        return Ok((root, blob));
                    }
                }
            }
            Err(Error::format(format!("{source}: invalid {kind}: {first}")))
        }
    }
}

/// Gives every scene object without `nodes` an empty list; `true` when something changed.
fn add_missing_scene_nodes(value: &mut serde_json::Value) -> bool {
    let Some(scenes) = value.get_mut("scenes").and_then(|s| s.as_array_mut()) else {
        return false;
    };
    let mut changed = false;
    for scene in scenes {
        if let Some(obj) = scene.as_object_mut() {
            if !obj.contains_key("nodes") {
                obj.insert("nodes".into(), serde_json::Value::Array(Vec::new()));
                changed = true;
            }
        }
    }
    changed
}

/// The spec requires `min`/`max` on POSITION accessors, but bounds are computed from the data
/// here, so files that omit them (many exporters do) are accepted.
fn is_missing_position_bounds(
    path: &gltf::json::Path,
    err: &gltf::json::validation::Error,
) -> bool {
    let p = path.as_str();
    matches!(err, gltf::json::validation::Error::Missing)
        && (p.ends_with("[\"POSITION\"].min") || p.ends_with("[\"POSITION\"].max"))
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
