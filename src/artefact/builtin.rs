//! Built-in artefacts, generated as GLB bytes: what the demo, the composite evaluation and the
//! host examples insert without any file, and what tests load through the real glTF loader.
//!
//! Each shape rests on its origin (lowest point at y = 0, centred on the Y axis) and is about
//! 0.2 m tall, in glTF's metres with +Y up.

use crate::error::{Error, Result};

/// Names accepted by [`builtin_glb`].
pub const BUILTIN_ARTEFACTS: &[&str] = &["sphere", "box", "metal-sphere"];

/// A triangle mesh with one glTF metallic-roughness material, before encoding.
struct Shape {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    indices: Vec<u32>,
    base_color: [f32; 4],
    metallic: f32,
    roughness: f32,
}

/// The GLB of built-in artefact `name` ([`BUILTIN_ARTEFACTS`]):
/// - `sphere`: glossy red plastic (base colour 0.8, 0.1, 0.1; roughness 0.25), radius 0.1 m;
/// - `box`: diffuse blue (0.2, 0.3, 0.8; roughness 0.9), a 0.2 m cube;
/// - `metal-sphere`: polished gold metal (1.0, 0.77, 0.34; metallic 1, roughness 0.15).
///
/// # Errors
/// `InvalidArgument` for an unknown name.
pub fn builtin_glb(name: &str) -> Result<Vec<u8>> {
    let shape = match name {
        "sphere" => sphere(0.1, [0.8, 0.1, 0.1, 1.0], 0.0, 0.25),
        "metal-sphere" => sphere(0.1, [1.0, 0.77, 0.34, 1.0], 1.0, 0.15),
        "box" => cube(0.1, [0.2, 0.3, 0.8, 1.0], 0.0, 0.9),
        other => {
            return Err(Error::invalid(format!(
                "unknown built-in artefact {other:?}; known: {}",
                BUILTIN_ARTEFACTS.join(", ")
            )))
        }
    };
    encode(&shape)
}

fn sphere(radius: f32, base_color: [f32; 4], metallic: f32, roughness: f32) -> Shape {
    const RINGS: u32 = 24;
    const SEGMENTS: u32 = 48;
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    for ring in 0..=RINGS {
        let theta = std::f32::consts::PI * ring as f32 / RINGS as f32;
        for segment in 0..=SEGMENTS {
            let phi = std::f32::consts::TAU * segment as f32 / SEGMENTS as f32;
            let n = [
                theta.sin() * phi.cos(),
                theta.cos(),
                -theta.sin() * phi.sin(),
            ];
            normals.push(n);
            positions.push([radius * n[0], radius * (n[1] + 1.0), radius * n[2]]);
        }
    }
    let mut indices = Vec::new();
    let row = SEGMENTS + 1;
    for ring in 0..RINGS {
        for segment in 0..SEGMENTS {
            let a = ring * row + segment;
            let b = a + row;
            // Counter-clockwise seen from outside: down the ring, then along +phi (towards −Z
            // from +X, i.e. counter-clockwise seen from +Y).
            // The first and last rings meet at a pole: one of each quad's triangles is empty.
            if ring > 0 {
                indices.extend([a, b, a + 1]);
            }
            if ring + 1 < RINGS {
                indices.extend([a + 1, b, b + 1]);
            }
        }
    }
    Shape {
        positions,
        normals,
        indices,
        base_color,
        metallic,
        roughness,
    }
}

fn cube(half: f32, base_color: [f32; 4], metallic: f32, roughness: f32) -> Shape {
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    let mut indices = Vec::new();
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let base = positions.len() as u32;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                let mut p = [0.0f32; 3];
                p[axis] = sign * half;
                p[u] = a * half;
                p[v] = b * half;
                p[1] += half;
                let mut n = [0.0f32; 3];
                n[axis] = sign;
                positions.push(p);
                normals.push(n);
            }
            // (u, v, axis) is right-handed, so the corners above run counter-clockwise seen from
            // +axis; the −axis face is wound the other way.
            let quad: [u32; 6] = if sign > 0.0 {
                [0, 1, 2, 0, 2, 3]
            } else {
                [0, 2, 1, 0, 3, 2]
            };
            indices.extend(quad.iter().map(|i| base + i));
        }
    }
    Shape {
        positions,
        normals,
        indices,
        base_color,
        metallic,
        roughness,
    }
}

fn encode(shape: &Shape) -> Result<Vec<u8>> {
    let mut min = [f32::INFINITY; 3];
    let mut max = [f32::NEG_INFINITY; 3];
    for p in &shape.positions {
        for k in 0..3 {
            min[k] = min[k].min(p[k]);
            max[k] = max[k].max(p[k]);
        }
    }
    let mut bin: Vec<u8> = Vec::new();
    bin.extend(
        shape
            .positions
            .iter()
            .flatten()
            .flat_map(|f| f.to_le_bytes()),
    );
    let normals_at = bin.len();
    bin.extend(shape.normals.iter().flatten().flat_map(|f| f.to_le_bytes()));
    let indices_at = bin.len();
    bin.extend(shape.indices.iter().flat_map(|i| i.to_le_bytes()));
    let vertices = shape.positions.len();
    let doc = serde_json::json!({
        "asset": {"version": "2.0", "generator": "parallax built-in artefact"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{
            "attributes": {"POSITION": 0, "NORMAL": 1},
            "indices": 2,
            "material": 0
        }]}],
        "materials": [{"pbrMetallicRoughness": {
            "baseColorFactor": shape.base_color,
            "metallicFactor": shape.metallic,
            "roughnessFactor": shape.roughness
        }}],
        "buffers": [{"byteLength": bin.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": normals_at},
            {"buffer": 0, "byteOffset": normals_at, "byteLength": indices_at - normals_at},
            {"buffer": 0, "byteOffset": indices_at, "byteLength": bin.len() - indices_at}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": vertices, "type": "VEC3",
             "min": min, "max": max},
            {"bufferView": 1, "componentType": 5126, "count": vertices, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5125, "count": shape.indices.len(), "type": "SCALAR"}
        ]
    });
    let mut json =
        serde_json::to_vec(&doc).map_err(|e| Error::Internal(format!("built-in GLB JSON: {e}")))?;
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::artefact::{Artefact, LoadOptions};
    use glam::Vec3;

    #[test]
    fn every_builtin_loads_rests_on_its_origin_and_faces_outwards() {
        for name in BUILTIN_ARTEFACTS {
            let bytes = builtin_glb(name).unwrap();
            let artefact = Artefact::from_glb_bytes(&bytes, &LoadOptions::default()).unwrap();
            assert!(
                artefact.warnings.is_empty(),
                "{name}: {:?}",
                artefact.warnings
            );
            let b = artefact.bounds;
            assert!(
                b.min.y.abs() < 1e-5 && (b.max.y - 0.2).abs() < 1e-3,
                "{name} {b:?}"
            );
            assert!(
                b.center().x.abs() < 1e-5 && b.center().z.abs() < 1e-5,
                "{name}"
            );
            let centre = Vec3::new(0.0, 0.1, 0.0);
            for p in &artefact.primitives {
                // Counter-clockwise seen from outside: every face normal points away from the
                // centre, and agrees with the vertex normals.
                for t in p.indices.chunks_exact(3) {
                    let [a, b, c] = [0, 1, 2].map(|k| p.positions[t[k] as usize]);
                    let n = (b - a).cross(c - a);
                    assert!(n.length() > 1e-9, "{name}: degenerate triangle {t:?}");
                    let mid = (a + b + c) / 3.0;
                    assert!(n.dot(mid - centre) > 0.0, "{name}: inward triangle {t:?}");
                    assert!(n.dot(p.normals[t[0] as usize]) > 0.0, "{name}");
                }
            }
        }
        assert!(builtin_glb("teapot")
            .unwrap_err()
            .to_string()
            .contains("sphere"));
    }
}
