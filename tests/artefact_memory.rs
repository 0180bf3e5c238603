//! Assets built in code, loaded from memory: round trip of a textured box, instancing, and the
//! validation errors each kind of corruption must produce (no shared data needed).
#![cfg(feature = "gltf")]

mod artefact_support;

use std::sync::Arc;

use artefact_support::{box_faces, glb, textured_box};
use glam::{Mat4, Vec2, Vec3};
use parallax::artefact::{AlphaMode, Artefact, ArtefactSet, Filter, LoadLimits, LoadOptions, Wrap};
use parallax::Error;
use serde_json::json;

fn load(bytes: &[u8]) -> parallax::Result<Artefact> {
    Artefact::from_glb_bytes(bytes, &LoadOptions::default())
}

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() < 1e-6
}

#[test]
fn textured_box_round_trips_through_glb_bytes() {
    let asset = textured_box(0.5, [1.0, 2.0, 3.0]);
    let a = load(&asset.glb()).unwrap();
    assert!(a.warnings.is_empty(), "{:?}", a.warnings);
    assert_eq!(a.primitives.len(), 1);
    assert_eq!(a.triangle_count(), 12);
    assert_eq!(a.vertex_count(), 24);
    // The node translation is applied: the box spans t ± 0.5.
    assert!(
        close(a.bounds.min, Vec3::new(0.5, 1.5, 2.5)),
        "{:?}",
        a.bounds
    );
    assert!(
        close(a.bounds.max, Vec3::new(1.5, 2.5, 3.5)),
        "{:?}",
        a.bounds
    );

    let p = &a.primitives[0];
    let t = Vec3::new(1.0, 2.0, 3.0);
    // Every vertex keeps the normal and UV it was written with.
    let faces = box_faces(0.5);
    for (f, (n, corners)) in faces.iter().enumerate() {
        for (k, c) in corners.iter().enumerate() {
            let v = f * 4 + k;
            assert!(close(p.positions[v], Vec3::from(*c) + t));
            assert!(close(p.normals[v], Vec3::from(*n)));
            let uv = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]][k];
            assert_eq!(p.uv0.as_ref().unwrap()[v], Vec2::from(uv));
        }
    }
    // Winding: each triangle's geometric normal agrees with the vertex normals (CCW outside).
    for tri in p.indices.chunks_exact(3) {
        let [a0, b0, c0] = [0, 1, 2].map(|i| p.positions[tri[i] as usize]);
        let g = (b0 - a0).cross(c0 - a0).normalize();
        assert!(g.dot(p.normals[tri[0] as usize]) > 0.999);
    }
    assert!(p.tangents.is_none(), "no normal map, no tangents");
    assert!(p.uv1.is_none() && p.colors.is_none());

    let m = &a.materials[p.material];
    assert_eq!(m.name.as_deref(), Some("Painted"));
    assert_eq!(m.base_color_factor.to_array(), [1.0, 0.5, 0.25, 1.0]);
    assert_eq!((m.metallic_factor, m.roughness_factor), (0.0, 0.75));
    assert_eq!(m.alpha_mode, AlphaMode::Mask { cutoff: 0.3 });
    assert!(m.double_sided);
    let tex = m.base_color_texture.unwrap();
    assert_eq!(tex.tex_coord, 0);
    let texture = &a.textures[tex.texture];
    assert_eq!((texture.image.width, texture.image.height), (2, 2));
    assert_eq!(
        texture.image.rgba8,
        vec![255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 255, 255, 255, 255, 128]
    );
    assert_eq!(texture.sampler.wrap_u, Wrap::ClampToEdge);
    assert_eq!(texture.sampler.wrap_v, Wrap::MirroredRepeat);
    assert_eq!(texture.sampler.mag_filter, Filter::Nearest);
    assert_eq!(texture.sampler.min_filter, Filter::Nearest);
    assert_eq!(texture.sampler.mipmap_filter, None);
}

#[test]
fn embedded_gltf_json_loads_like_the_glb() {
    let asset = textured_box(0.5, [0.0, 0.0, 0.0]);
    let a = load(&asset.glb()).unwrap();
    let b = load(&asset.gltf_embedded()).unwrap();
    assert_eq!(a.primitives[0].positions, b.primitives[0].positions);
    assert_eq!(a.primitives[0].indices, b.primitives[0].indices);
    assert_eq!(a.textures[0].image.rgba8, b.textures[0].image.rgba8);
}

#[test]
fn instancing_shares_the_asset_data() {
    let a = Arc::new(load(&textured_box(0.5, [0.0, 0.0, 0.0]).glb()).unwrap());
    let mut set = ArtefactSet::new();
    let ids: Vec<_> = (0..100)
        .map(|i| {
            set.add(
                a.clone(),
                Mat4::from_translation(Vec3::new(i as f32, 0.0, 0.0)),
            )
            .unwrap()
        })
        .collect();
    assert_eq!(Arc::strong_count(&a), 101);
    for id in &ids {
        let inst = set.get(*id).unwrap();
        assert!(Arc::ptr_eq(&inst.artefact, &a));
        assert!(std::ptr::eq(
            inst.artefact.primitives[0].positions.as_ptr(),
            a.primitives[0].positions.as_ptr()
        ));
    }
    let last = set.get(ids[99]).unwrap().world_bounds();
    assert!(close(last.min, Vec3::new(98.5, -0.5, -0.5)));
    set.set_transform(ids[0], Mat4::from_scale(Vec3::splat(4.0)))
        .unwrap();
    assert!(close(
        set.get(ids[0]).unwrap().world_bounds().max,
        Vec3::splat(2.0)
    ));
    for id in ids {
        set.remove(id).unwrap();
    }
    assert_eq!(Arc::strong_count(&a), 1);
}

#[test]
fn the_same_image_is_decoded_once_for_two_textures() {
    let mut asset = textured_box(0.5, [0.0, 0.0, 0.0]);
    asset.json["textures"] = json!([{"source": 0, "sampler": 0}, {"source": 0}]);
    asset.json["materials"][0]["emissiveTexture"] = json!({"index": 1});
    asset.json["materials"][0]["emissiveFactor"] = json!([1.0, 1.0, 1.0]);
    asset.json["materials"][0]["extensions"] =
        json!({"KHR_materials_emissive_strength": {"emissiveStrength": 5.0}});
    asset.json["extensionsUsed"] = json!(["KHR_materials_emissive_strength"]);
    let a = load(&asset.glb()).unwrap();
    assert_eq!(a.textures.len(), 2);
    assert!(Arc::ptr_eq(&a.textures[0].image, &a.textures[1].image));
    assert_eq!(a.textures[1].sampler.wrap_u, Wrap::Repeat);
    let m = &a.materials[0];
    assert_eq!(m.emissive_strength, 5.0);
    assert_eq!(m.emissive_factor, Vec3::ONE);
}

#[test]
fn normal_map_gets_tangents_along_increasing_u() {
    let mut asset = textured_box(0.5, [0.0, 0.0, 0.0]);
    asset.json["materials"][0]["normalTexture"] = json!({"index": 0, "scale": 0.5});
    asset.json["materials"][0]["occlusionTexture"] = json!({"index": 0, "strength": 0.25});
    let a = load(&asset.glb()).unwrap();
    let p = &a.primitives[0];
    let m = &a.materials[p.material];
    assert_eq!(m.normal_scale, 0.5);
    assert_eq!(m.occlusion_strength, 0.25);
    let tangents = p.tangents.as_ref().expect("normal map needs tangents");
    let faces = box_faces(0.5);
    for (f, (_, c)) in faces.iter().enumerate() {
        // UV u grows from corner 0 to corner 1, v decreases from corner 1 to corner 2.
        let du = (Vec3::from(c[1]) - Vec3::from(c[0])).normalize();
        for k in 0..4 {
            let t = tangents[f * 4 + k];
            assert!(close(t.truncate(), du), "face {f}: {t} vs {du}");
            assert!(t.truncate().dot(p.normals[f * 4 + k]).abs() < 1e-6);
            // v runs opposite to the face's second edge, so the bitangent sign is −1.
            assert_eq!(t.w, -1.0);
        }
    }
}

#[test]
fn texture_transform_and_blend_mode_are_read() {
    let mut asset = textured_box(0.5, [0.0, 0.0, 0.0]);
    let m = &mut asset.json["materials"][0];
    m["alphaMode"] = json!("BLEND");
    m["pbrMetallicRoughness"]["baseColorTexture"] = json!({"index": 0, "extensions": {
        "KHR_texture_transform": {"offset": [0.5, 0.0], "rotation": 0.0, "scale": [2.0, 2.0]}}});
    asset.json["extensionsUsed"] = json!(["KHR_texture_transform"]);
    asset.json["extensionsRequired"] = json!(["KHR_texture_transform"]);
    let a = load(&asset.glb()).unwrap();
    let m = &a.materials[0];
    assert_eq!(m.alpha_mode, AlphaMode::Blend);
    let t = m.base_color_texture.unwrap().transform.unwrap();
    assert_eq!(t.apply(Vec2::new(0.25, 0.5)), Vec2::new(1.0, 1.0));
}

#[test]
fn missing_normals_are_generated_with_a_warning_and_mirroring_keeps_faces_outward() {
    let mut asset = textured_box(0.5, [0.0, 0.0, 0.0]);
    asset.json["meshes"][0]["primitives"][0]["attributes"] = json!({"POSITION": 0});
    asset.json["materials"][0]["pbrMetallicRoughness"]
        .as_object_mut()
        .unwrap()
        .remove("baseColorTexture");
    // A mirroring node (negative scale on x).
    asset.json["nodes"][0]["scale"] = json!([-1.0, 1.0, 1.0]);
    let a = load(&asset.glb()).unwrap();
    assert!(
        a.warnings.iter().any(|w| w.contains("no NORMAL")),
        "{:?}",
        a.warnings
    );
    let p = &a.primitives[0];
    for tri in p.indices.chunks_exact(3) {
        let [v0, v1, v2] = [0, 1, 2].map(|i| p.positions[tri[i] as usize]);
        let g = (v1 - v0).cross(v2 - v0);
        let centre = (v0 + v1 + v2) / 3.0;
        assert!(g.dot(centre) > 0.0, "triangle {tri:?} faces inward");
    }
    for (v, n) in p.positions.iter().zip(&p.normals) {
        assert!((n.length() - 1.0).abs() < 1e-5);
        // Area-weighted normals of a box corner point outward (into its octant).
        assert!(n.dot(*v) > 0.0);
    }
}

#[test]
fn strips_fans_and_8_bit_indices() {
    // A unit quad as a strip, a fan, and a u8-indexed list, side by side.
    let pos: [[f32; 3]; 4] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 0.0],
    ];
    let strip: [u8; 4] = [0, 1, 2, 3];
    let fan: [u8; 4] = [0, 1, 3, 2];
    let list: [u8; 6] = [0, 1, 3, 0, 3, 2];
    let mut bin: Vec<u8> = bytemuck::cast_slice(&pos).to_vec();
    bin.extend_from_slice(&strip);
    bin.extend_from_slice(&fan);
    bin.extend_from_slice(&list);
    let prim =
        |mode: u32, acc: u32| json!({"attributes": {"POSITION": 0}, "indices": acc, "mode": mode});
    let doc = json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0, 1, 2]}],
        "nodes": [{"mesh": 0}, {"mesh": 1, "translation": [2.0, 0.0, 0.0]},
                  {"mesh": 2, "matrix": [1.0,0.0,0.0,0.0, 0.0,1.0,0.0,0.0, 0.0,0.0,1.0,0.0, 4.0,0.0,0.0,1.0]}],
        "meshes": [{"primitives": [prim(5, 1)]}, {"primitives": [prim(6, 2)]}, {"primitives": [prim(4, 3)]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0.0,0.0,0.0], "max": [1.0,1.0,0.0]},
            {"bufferView": 1, "componentType": 5121, "count": 4, "type": "SCALAR"},
            {"bufferView": 1, "byteOffset": 4, "componentType": 5121, "count": 4, "type": "SCALAR"},
            {"bufferView": 1, "byteOffset": 8, "componentType": 5121, "count": 6, "type": "SCALAR"}
        ],
        "bufferViews": [{"buffer": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 14}],
        "buffers": [{"byteLength": bin.len()}]
    });
    let a = load(&glb(&doc, &bin)).unwrap();
    assert_eq!(a.primitives.len(), 3);
    for p in &a.primitives {
        assert_eq!(p.triangle_count(), 2);
        for tri in p.indices.chunks_exact(3) {
            let [v0, v1, v2] = [0, 1, 2].map(|i| p.positions[tri[i] as usize]);
            // All front faces point at +Z (CCW), covering area 0.5 each.
            let c = (v1 - v0).cross(v2 - v0);
            assert!(
                (c - Vec3::new(0.0, 0.0, 1.0)).length() < 1e-6,
                "{tri:?} {c}"
            );
        }
        for n in &p.normals {
            assert!(close(*n, Vec3::Z));
        }
    }
    assert!(close(a.bounds.max, Vec3::new(5.0, 1.0, 0.0)));
}

/// Loads `doc` + `bin` and returns the error message, checking its kind.
fn error_of(doc: &serde_json::Value, bin: &[u8]) -> Error {
    match load(&glb(doc, bin)) {
        Ok(a) => panic!("expected an error, loaded {} triangles", a.triangle_count()),
        Err(e) => e,
    }
}

#[test]
fn corruptions_give_errors_that_name_the_problem() {
    let base = textured_box(0.5, [0.0, 0.0, 0.0]);
    type Edit = fn(&mut serde_json::Value);
    type Kind = fn(&Error) -> bool;
    let cases: Vec<(&str, Edit, &str, Kind)> = vec![
        (
            "index out of range",
            |j| {
                for a in 0..3 {
                    j["accessors"][a]["count"] = json!(12);
                }
            },
            "out of range for 12 vertices",
            |e| matches!(e, Error::Format(_)),
        ),
        (
            "accessor past its view",
            |j| j["accessors"][1]["byteOffset"] = json!(8),
            "accessor 1",
            |e| matches!(e, Error::Format(_)),
        ),
        (
            "view past its buffer",
            |j| j["bufferViews"][0]["byteLength"] = json!(100000),
            "bufferView 0",
            |e| matches!(e, Error::Format(_)),
        ),
        (
            "stride smaller than an element",
            |j| j["bufferViews"][1]["byteStride"] = json!(4),
            "byteStride 4",
            |e| matches!(e, Error::Format(_)),
        ),
        (
            "float indices",
            |j| j["accessors"][3]["componentType"] = json!(5126),
            "indices",
            |e| matches!(e, Error::Format(_)),
        ),
        (
            "positions as VEC2",
            |j| j["accessors"][0]["type"] = json!("VEC2"),
            "POSITION",
            |e| matches!(e, Error::Format(_)),
        ),
        (
            "attribute counts differ",
            |j| j["accessors"][2]["count"] = json!(20),
            "20 elements",
            |e| matches!(e, Error::Format(_)),
        ),
        (
            "node cycle",
            |j| {
                j["nodes"] =
                    json!([{"mesh": 0, "children": [1]}, {"children": [2]}, {"children": [1]}])
            },
            "node cycle: 1 → 2 → 1",
            |e| matches!(e, Error::Format(_)),
        ),
        (
            "node with two parents",
            |j| {
                j["nodes"] = json!([{"mesh": 0, "children": [2]}, {"children": [2]}, {}]);
                j["scenes"] = json!([{"nodes": [0, 1]}]);
            },
            "node 2",
            |e| matches!(e, Error::Format(_)),
        ),
        (
            "dangling index",
            |j| j["meshes"][0]["primitives"][0]["material"] = json!(7),
            "material",
            |e| matches!(e, Error::Format(_)),
        ),
        (
            "required Draco",
            |j| {
                j["extensionsUsed"] = json!(["KHR_draco_mesh_compression"]);
                j["extensionsRequired"] = json!(["KHR_draco_mesh_compression"]);
            },
            "KHR_draco_mesh_compression",
            |e| matches!(e, Error::Unsupported(_)),
        ),
        (
            "required meshopt",
            |j| j["extensionsRequired"] = json!(["EXT_meshopt_compression"]),
            "EXT_meshopt_compression",
            |e| matches!(e, Error::Unsupported(_)),
        ),
        (
            "required basisu",
            |j| j["extensionsRequired"] = json!(["KHR_texture_basisu"]),
            "KHR_texture_basisu",
            |e| matches!(e, Error::Unsupported(_)),
        ),
        (
            "network URI",
            |j| j["buffers"][0]["uri"] = json!("https://example.com/box.bin"),
            "https:",
            |e| matches!(e, Error::InvalidArgument(_)),
        ),
        (
            "escaping URI",
            |j| j["images"][0] = json!({"uri": "../../etc/passwd"}),
            "../../etc/passwd",
            |e| matches!(e, Error::InvalidArgument(_)),
        ),
        (
            "glTF 1.0",
            |j| j["asset"]["version"] = json!("1.0"),
            "1.0",
            |e| matches!(e, Error::Unsupported(_)),
        ),
        (
            "triangle list not a multiple of 3",
            |j| j["accessors"][3]["count"] = json!(35),
            "35 indices",
            |e| matches!(e, Error::Format(_)),
        ),
        (
            "zero quaternion",
            |j| j["nodes"][0]["rotation"] = json!([0.0, 0.0, 0.0, 0.0]),
            "node 0",
            |e| matches!(e, Error::Format(_)),
        ),
        (
            "image with neither uri nor bufferView (found by the fuzzer)",
            |j| j["images"][0] = json!({}),
            "neither a uri nor a bufferView",
            |e| matches!(e, Error::Format(_)),
        ),
        (
            "dangling POSITION index (found by the fuzzer)",
            |j| j["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(9),
            "POSITION refers to accessor 9",
            |e| matches!(e, Error::Format(_)),
        ),
        (
            "image that is not PNG or JPEG",
            |j| j["images"][0] = json!({"bufferView": 0, "mimeType": "image/png"}),
            "image 0",
            |e| matches!(e, Error::Unsupported(_)),
        ),
    ];
    for (name, edit, needle, kind) in cases {
        let mut doc = base.json.clone();
        edit(&mut doc);
        eprintln!("case: {name}");
        let e = error_of(&doc, &base.bin);
        assert!(kind(&e), "{name}: wrong kind: {e}");
        assert!(
            e.to_string().contains(needle),
            "{name}: '{e}' lacks '{needle}'"
        );
    }
}

#[test]
fn image_in_a_buffer_view_without_mime_type_is_recognised_by_its_bytes() {
    // Found by the fuzzer: the `gltf` crate unwraps the missing mimeType.
    let mut asset = textured_box(0.5, [0.0, 0.0, 0.0]);
    asset.json["images"][0] = json!({"bufferView": 4});
    let a = load(&asset.glb()).unwrap();
    assert_eq!(a.textures[0].image.width, 2);
}

#[test]
fn infinite_positions_are_an_error_naming_the_vertex() {
    let mut asset = textured_box(0.5, [0.0, 0.0, 0.0]);
    asset.bin[12..16].copy_from_slice(&f32::INFINITY.to_le_bytes());
    let e = load(&asset.glb()).unwrap_err();
    assert!(e.to_string().contains("vertex 1 is not finite"), "{e}");
}

#[test]
fn external_files_from_memory_need_a_folder_and_stay_inside_it() {
    let asset = textured_box(0.5, [0.0, 0.0, 0.0]);
    let mut j = asset.json.clone();
    j["buffers"][0]["uri"] = json!("box.bin");
    let text = serde_json::to_vec(&j).unwrap();
    let e = load(&text).unwrap_err();
    assert!(matches!(e, Error::InvalidArgument(_)), "{e}");
    assert!(e.to_string().contains("box.bin"));

    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("box.bin"), &asset.bin).unwrap();
    std::fs::write(dir.path().join("box.gltf"), &text).unwrap();
    let a = Artefact::from_path(dir.path().join("box.gltf"), &LoadOptions::default()).unwrap();
    assert_eq!(a.triangle_count(), 12);
    let b = Artefact::from_bytes_in(&text, dir.path(), &LoadOptions::default()).unwrap();
    assert_eq!(b.triangle_count(), 12);
    let e =
        Artefact::from_path(dir.path().join("missing.gltf"), &LoadOptions::default()).unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e}");
}

#[test]
fn caps_on_vertices_textures_and_memory() {
    let asset = textured_box(0.5, [0.0, 0.0, 0.0]);
    let with = |limits: LoadLimits| Artefact::from_glb_bytes(&asset.glb(), &LoadOptions { limits });
    let e = with(LoadLimits {
        max_vertices: 23,
        ..LoadLimits::default()
    })
    .unwrap_err();
    assert!(
        matches!(e, Error::TooLarge(_)) && e.to_string().contains("max_vertices"),
        "{e}"
    );
    let e = with(LoadLimits {
        max_triangles: 11,
        ..LoadLimits::default()
    })
    .unwrap_err();
    assert!(
        matches!(e, Error::TooLarge(_)) && e.to_string().contains("max_triangles"),
        "{e}"
    );
    let e = with(LoadLimits {
        max_texture_side: 1,
        ..LoadLimits::default()
    })
    .unwrap_err();
    assert!(e.to_string().contains("image 0"), "{e}");
    let e = with(LoadLimits {
        max_total_bytes: 1000,
        ..LoadLimits::default()
    })
    .unwrap_err();
    assert!(matches!(e, Error::TooLarge(_)), "{e}");
    assert!(with(LoadLimits {
        max_vertices: 24,
        max_triangles: 12,
        max_texture_side: 2,
        ..LoadLimits::default()
    })
    .is_ok());
}

#[test]
fn missing_uv_set_drops_the_texture_with_a_warning() {
    let mut asset = textured_box(0.5, [0.0, 0.0, 0.0]);
    asset.json["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["texCoord"] = json!(1);
    let a = load(&asset.glb()).unwrap();
    let m = &a.materials[a.primitives[0].material];
    assert!(m.base_color_texture.is_none());
    assert!(
        a.warnings.iter().any(|w| w.contains("TEXCOORD_1")),
        "{:?}",
        a.warnings
    );
}

#[test]
fn sparse_accessors_override_elements() {
    let mut asset = textured_box(0.5, [0.0, 0.0, 0.0]);
    // Move vertex 0 to (−2, −2, −2) through a sparse block appended to the buffer.
    let at = asset.bin.len();
    asset.bin.extend_from_slice(&0u16.to_le_bytes());
    asset.bin.extend_from_slice(&[0, 0]);
    for _ in 0..3 {
        asset.bin.extend_from_slice(&(-2.0f32).to_le_bytes());
    }
    let views = asset.json["bufferViews"].as_array_mut().unwrap();
    views.push(json!({"buffer": 0, "byteOffset": at, "byteLength": 2}));
    views.push(json!({"buffer": 0, "byteOffset": at + 4, "byteLength": 12}));
    asset.json["buffers"][0]["byteLength"] = json!(asset.bin.len());
    asset.json["accessors"][0]["sparse"] = json!({"count": 1,
        "indices": {"bufferView": 5, "componentType": 5123},
        "values": {"bufferView": 6}});
    let a = load(&asset.glb()).unwrap();
    assert_eq!(a.primitives[0].positions[0], Vec3::splat(-2.0));
    assert_eq!(a.bounds.min, Vec3::splat(-2.0));
    // A sparse index past the count is an error naming it.
    asset.bin[at..at + 2].copy_from_slice(&30u16.to_le_bytes());
    let e = load(&asset.glb()).unwrap_err();
    assert!(e.to_string().contains("sparse index 0 is 30"), "{e}");
}
