//! Builds glTF assets in code for the artefact tests (no shared data needed).
#![allow(dead_code)]

use serde_json::{json, Value};

/// Packs a glTF JSON document and a binary chunk into GLB bytes (spec §4.4).
pub fn glb(doc: &Value, bin: &[u8]) -> Vec<u8> {
    let mut json = serde_json::to_vec(doc).unwrap();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut bin = bin.to_vec();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    let total = 12 + 8 + json.len() + if bin.is_empty() { 0 } else { 8 + bin.len() };
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    if !bin.is_empty() {
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
    }
    out
}

/// A 2×2 RGBA PNG: red, green / blue, white (alpha 255, except white: 128).
pub fn png_2x2() -> Vec<u8> {
    let pixels = [
        [255u8, 0, 0, 255],
        [0, 255, 0, 255],
        [0, 0, 255, 255],
        [255, 255, 255, 128],
    ];
    let img = image::RgbaImage::from_fn(2, 2, |x, y| image::Rgba(pixels[(y * 2 + x) as usize]));
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    png
}

/// The six faces of an axis-aligned box of half-size `h`: (outward normal, four corners CCW seen
/// from outside).
pub fn box_faces(h: f32) -> Vec<([f32; 3], [[f32; 3]; 4])> {
    let mut faces = Vec::new();
    for axis in 0..3 {
        for sign in [1.0f32, -1.0] {
            let mut n = [0.0; 3];
            n[axis] = sign;
            // Two tangent axes such that (u × v) = n.
            let (u_axis, v_axis) = ((axis + 1) % 3, (axis + 2) % 3);
            let corner = |a: f32, b: f32| {
                let mut p = [0.0; 3];
                p[axis] = sign * h;
                p[u_axis] = a * h * sign;
                p[v_axis] = b * h;
                p
            };
            faces.push((
                n,
                [
                    corner(-1.0, -1.0),
                    corner(1.0, -1.0),
                    corner(1.0, 1.0),
                    corner(-1.0, 1.0),
                ],
            ));
        }
    }
    faces
}

/// Parts of the textured box asset, so tests can alter the JSON before packing.
pub struct BoxAsset {
    pub json: Value,
    pub bin: Vec<u8>,
}

/// A textured box of half-size `h` (24 vertices, 36 u16 indices, normals, UVs, an embedded 2×2
/// PNG with a clamp/nearest sampler), under a node translated by `t`.
pub fn textured_box(h: f32, t: [f32; 3]) -> BoxAsset {
    let mut pos = Vec::new();
    let mut nor = Vec::new();
    let mut uv = Vec::new();
    let mut idx: Vec<u16> = Vec::new();
    for (f, (n, corners)) in box_faces(h).into_iter().enumerate() {
        for (k, c) in corners.iter().enumerate() {
            pos.extend_from_slice(c);
            nor.extend_from_slice(&n);
            let uvk = [[0.0f32, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]][k];
            uv.extend_from_slice(&uvk);
        }
        let b = (f * 4) as u16;
        idx.extend_from_slice(&[b, b + 1, b + 2, b, b + 2, b + 3]);
    }
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut push = |bytes: &[u8], bin: &mut Vec<u8>| {
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let offset = bin.len();
        bin.extend_from_slice(bytes);
        views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": bytes.len()}));
    };
    push(bytemuck::cast_slice(&pos), &mut bin);
    push(bytemuck::cast_slice(&nor), &mut bin);
    push(bytemuck::cast_slice(&uv), &mut bin);
    push(bytemuck::cast_slice(&idx), &mut bin);
    push(&png_2x2(), &mut bin);
    let json = json!({
        "asset": {"version": "2.0", "generator": "parallax tests"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "translation": t, "name": "box"}],
        "meshes": [{"name": "Box", "primitives": [{
            "attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2},
            "indices": 3, "material": 0}]}],
        "materials": [{
            "name": "Painted",
            "pbrMetallicRoughness": {
                "baseColorFactor": [1.0, 0.5, 0.25, 1.0],
                "baseColorTexture": {"index": 0},
                "metallicFactor": 0.0,
                "roughnessFactor": 0.75
            },
            "alphaMode": "MASK",
            "alphaCutoff": 0.3,
            "doubleSided": true
        }],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"magFilter": 9728, "minFilter": 9728, "wrapS": 33071, "wrapT": 33648}],
        "images": [{"bufferView": 4, "mimeType": "image/png"}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 24, "type": "VEC3",
             "min": [-h, -h, -h], "max": [h, h, h]},
            {"bufferView": 1, "componentType": 5126, "count": 24, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5126, "count": 24, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5123, "count": 36, "type": "SCALAR"}
        ],
        "bufferViews": views,
        "buffers": [{"byteLength": bin.len()}]
    });
    BoxAsset { json, bin }
}

impl BoxAsset {
    /// The asset as GLB bytes.
    pub fn glb(&self) -> Vec<u8> {
        glb(&self.json, &self.bin)
    }

    /// The asset as `.gltf` JSON with the buffer embedded as a base64 data URI.
    pub fn gltf_embedded(&self) -> Vec<u8> {
        let mut j = self.json.clone();
        j["buffers"][0]["uri"] = Value::String(format!(
            "data:application/octet-stream;base64,{}",
            base64(&self.bin)
        ));
        serde_json::to_vec(&j).unwrap()
    }
}

/// Standard base64 with padding (tests only; the loader has its own decoder).
pub fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in bytes.chunks(3) {
        let n = (c[0] as u32) << 16
            | (*c.get(1).unwrap_or(&0) as u32) << 8
            | *c.get(2).unwrap_or(&0) as u32;
        for i in 0..4 {
            if i <= c.len() {
                s.push(A[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// The shared data folder's glTF directory, or `None` (tests then skip).
pub fn data_dir() -> Option<std::path::PathBuf> {
    let root = std::env::var_os("PARALLAX_DATA")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data").into());
    let dir = root.join("gltf");
    dir.is_dir().then_some(dir)
}
