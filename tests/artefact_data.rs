//! Every model of the shared glTF collection (`../shared/data/gltf`, see its README): the valid
//! ones load with the triangle count and bounds computed independently from the files by
//! `scripts/gltf_expected.py` (plain JSON + struct), the broken ones fail with an error naming the
//! problem, the repairable ones load with a warning. Skipped when the data folder is absent.
#![cfg(feature = "gltf")]
// The script prints 9 significant digits, more than f32 holds; kept verbatim.
#![allow(clippy::excessive_precision)]

mod artefact_support;

use glam::Vec3;
use parallax::artefact::{Artefact, LoadOptions};
use parallax::Error;

/// (file, triangles, min, max) from `python3 scripts/gltf_expected.py`.
const EXPECTED: &[(&str, usize, [f32; 3], [f32; 3])] = &[
    (
        "BoxTextured-glTF/BoxTextured.gltf",
        12,
        [-0.5, -0.5, -0.5],
        [0.5, 0.5, 0.5],
    ),
    (
        "BoxTextured-glTF-Binary/BoxTextured.glb",
        12,
        [-0.5, -0.5, -0.5],
        [0.5, 0.5, 0.5],
    ),
    (
        "BoxTextured-glTF-Embedded/BoxTextured.gltf",
        12,
        [-0.5, -0.5, -0.5],
        [0.5, 0.5, 0.5],
    ),
    (
        "BoxTextured-glTF-pbrSpecularGlossiness/BoxTextured.gltf",
        12,
        [-0.5, -0.5, -0.5],
        [0.5, 0.5, 0.5],
    ),
    (
        "BoxTexcoords-glTF/boxTexcoords.gltf",
        12,
        [-1.0, -1.0, -1.0],
        [1.0, 1.0, 1.0],
    ),
    (
        "BoxBadNormals-glTF-Binary/BoxBadNormals.glb",
        12,
        [-0.5, -0.5, -0.5],
        [0.5, 0.5, 0.5],
    ),
    (
        "2CylinderEngine-glTF-Binary/2CylinderEngine.glb",
        121496,
        [-371.692263, -180.971558, -139.999993],
        [371.692169, 92.0415617, 127.999996],
    ),
    (
        "ClearCoat-glTF/ClearCoatTest.gltf",
        37116,
        [-7.35780334, -6.25, -0.0600000098],
        [3.0999999, 6.85451686, 1.04999995],
    ),
    (
        "textureTransform/TextureTransformTest.gltf",
        24,
        [-1.6, -1.14126749, 0.0],
        [1.6, 1.05, 0.01],
    ),
    (
        "glTF-Sample-Models/AnimatedMorphCube-glTF/AnimatedMorphCube.gltf",
        12,
        [-1.00000017, -0.999999943, -1.00000012],
        [1.00000027, 0.999999943, 1.00000022],
    ),
    (
        "cameras/Cameras.gltf",
        2,
        [0.0, 0.0, -0.7075925],
        [1.0, 0.706622, 0.0],
    ),
    (
        "simple_skin/simple_skin.gltf",
        8,
        [0.0, 0.0, 0.0],
        [1.0, 2.0, 0.0],
    ),
    (
        "issue_3269/texcoord_crash.gltf",
        10,
        [-1.20000017, -1.20000017, -0.0525911525],
        [1.20000017, 1.20000017, 5.25511837e-07],
    ),
    (
        "TestNoRootNode/NoScene.gltf",
        0,
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0],
    ),
    (
        "TestNoRootNode/SceneWithoutNodes.gltf",
        0,
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0],
    ),
    (
        "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_00.gltf",
        0,
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0],
    ),
    (
        "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_01.gltf",
        0,
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0],
    ),
    (
        "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_02.gltf",
        0,
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0],
    ),
    (
        "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_03.gltf",
        0,
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0],
    ),
    (
        "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_04.gltf",
        2,
        [-0.5, -0.5, 0.0],
        [0.5, 0.5, 0.0],
    ),
    (
        "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_05.gltf",
        2,
        [-0.5, -0.5, 0.0],
        [0.5, 0.5, 0.0],
    ),
    (
        "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_06.gltf",
        2,
        [-0.5, -0.5, 0.0],
        [0.5, 0.5, 0.0],
    ),
    (
        "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_07.gltf",
        0,
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0],
    ),
    (
        "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_08.gltf",
        0,
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0],
    ),
    (
        "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_09.gltf",
        0,
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0],
    ),
    (
        "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_10.gltf",
        0,
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0],
    ),
    (
        "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_11.gltf",
        2,
        [-0.5, -0.5, 0.0],
        [0.5, 0.5, 0.0],
    ),
    (
        "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_12.gltf",
        2,
        [-0.5, -0.5, 0.0],
        [0.5, 0.5, 0.0],
    ),
    (
        "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_13.gltf",
        2,
        [-0.5, -0.5, 0.0],
        [0.5, 0.5, 0.0],
    ),
    (
        "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_14.gltf",
        2,
        [-0.5, -0.5, 0.0],
        [0.5, 0.5, 0.0],
    ),
    (
        "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_15.gltf",
        2,
        [-0.5, -0.5, 0.0],
        [0.5, 0.5, 0.0],
    ),
];

fn load(dir: &std::path::Path, file: &str) -> parallax::Result<Artefact> {
    Artefact::from_path(dir.join(file), &LoadOptions::default())
}

#[test]
fn valid_models_load_with_the_right_triangle_count_and_bounds() {
    let Some(dir) = artefact_support::data_dir() else {
        eprintln!("skipped: shared glTF data not found");
        return;
    };
    for &(file, triangles, min, max) in EXPECTED {
        let a = load(&dir, file).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert_eq!(a.triangle_count(), triangles, "{file}");
        let (min, max) = (Vec3::from(min), Vec3::from(max));
        let tolerance = 1e-5 * (max - min).max_element().max(1.0);
        assert!(
            (a.bounds.min - min).abs().max_element() <= tolerance
                && (a.bounds.max - max).abs().max_element() <= tolerance,
            "{file}: bounds {:?}, expected {min} .. {max}",
            a.bounds
        );
        for p in &a.primitives {
            let n = p.positions.len();
            assert!(p.indices.iter().all(|&i| (i as usize) < n), "{file}");
            assert_eq!(p.normals.len(), n);
            assert!(
                p.normals
                    .iter()
                    .all(|v| v.is_finite() && (v.length() - 1.0).abs() < 1e-3),
                "{file}: normals must be finite unit vectors"
            );
            assert!(p.positions.iter().all(|v| v.is_finite()));
            if let Some(t) = &p.tangents {
                assert!(t.iter().all(|t| t.is_finite() && t.w.abs() == 1.0));
            }
            assert!(p.material < a.materials.len());
        }
        for m in &a.materials {
            for (_, t) in m.texture_slots() {
                assert!(t.texture < a.textures.len(), "{file}");
            }
        }
    }
}

#[test]
fn texture_and_material_details_of_known_models() {
    let Some(dir) = artefact_support::data_dir() else {
        return;
    };
    // BoxTextured: one 211×211 PNG shared by the three encodings, identical pixels.
    let files = [
        "BoxTextured-glTF/BoxTextured.gltf",
        "BoxTextured-glTF-Binary/BoxTextured.glb",
        "BoxTextured-glTF-Embedded/BoxTextured.gltf",
    ];
    let loaded: Vec<Artefact> = files.iter().map(|f| load(&dir, f).unwrap()).collect();
    for a in &loaded {
        assert_eq!(a.textures.len(), 1);
        let img = &a.textures[0].image;
        assert_eq!((img.width, img.height), (211, 211));
        assert_eq!(img.rgba8, loaded[0].textures[0].image.rgba8);
        assert_eq!(a.materials[0].metallic_factor, 0.0);
    }
    // ClearCoat: optional KHR_materials_clearcoat is reported and ignored.
    let a = load(&dir, "ClearCoat-glTF/ClearCoatTest.gltf").unwrap();
    assert!(a
        .warnings
        .iter()
        .any(|w| w.contains("KHR_materials_clearcoat")));
    // The normal-mapped materials get tangents.
    assert!(a.primitives.iter().any(|p| p.tangents.is_some()));
    // TextureTransformTest: the transforms are read.
    let a = load(&dir, "textureTransform/TextureTransformTest.gltf").unwrap();
    let transformed = a
        .materials
        .iter()
        .filter(|m| m.base_color_texture.is_some_and(|t| t.transform.is_some()))
        .count();
    assert!(transformed >= 5, "{transformed}");
}

#[test]
fn box_bad_normals_is_repaired_with_a_warning() {
    let Some(dir) = artefact_support::data_dir() else {
        return;
    };
    let a = load(&dir, "BoxBadNormals-glTF-Binary/BoxBadNormals.glb").unwrap();
    assert!(
        a.warnings.iter().any(|w| w.contains("recomputed")),
        "{:?}",
        a.warnings
    );
    assert!(a.warnings.iter().any(|w| w.contains("renormalised")));
    // Every vertex normal now agrees with the geometric normal of the triangles using it.
    let p = &a.primitives[0];
    for tri in p.indices.chunks_exact(3) {
        let [v0, v1, v2] = [0, 1, 2].map(|i| p.positions[tri[i] as usize]);
        let g = (v1 - v0).cross(v2 - v0).normalize();
        for &i in tri {
            assert!(p.normals[i as usize].dot(g) > 0.999, "{tri:?}");
        }
    }
}

#[test]
fn texcoord_crash_model_drops_the_unreadable_texture_with_a_warning() {
    let Some(dir) = artefact_support::data_dir() else {
        return;
    };
    let a = load(&dir, "issue_3269/texcoord_crash.gltf").unwrap();
    assert!(
        a.warnings.iter().any(|w| w.contains("TEXCOORD_0")),
        "{:?}",
        a.warnings
    );
    for p in &a.primitives {
        for (_, t) in a.materials[p.material].texture_slots() {
            let has = match t.tex_coord {
                0 => p.uv0.is_some(),
                1 => p.uv1.is_some(),
                _ => false,
            };
            assert!(has, "a primitive samples a UV set it lacks");
        }
    }
}

#[test]
fn broken_models_fail_with_errors_that_name_the_problem() {
    let Some(dir) = artefact_support::data_dir() else {
        return;
    };
    type Kind = fn(&Error) -> bool;
    let format: Kind = |e| matches!(e, Error::Format(_));
    let cases: &[(&str, Kind, &[&str])] = &[
        (
            "RecursiveNodes/RecursiveNodes.gltf",
            format,
            &["node cycle: 0 → 1 → 0"],
        ),
        (
            "IndexOutOfRange/IndexOutOfRange.gltf",
            format,
            &["accessor 0", "is 255", "out of range for 24 vertices"],
        ),
        (
            "IndexOutOfRange/AllIndicesOutOfRange.gltf",
            format,
            &["accessor 0", "out of range for 24 vertices"],
        ),
        (
            "IncorrectVertexArrays/Cube.gltf",
            format,
            &["TruncatedCube", "35 vertices, not a multiple of 3"],
        ),
        (
            "MissingBin/BoxTextured.gltf",
            |e| matches!(e, Error::Io { .. }),
            &["BoxTextured0.bin"],
        ),
        (
            "SchemaFailures/sceneWrongType.gltf",
            format,
            &["\"hello\"", "line 6"],
        ),
        (
            "wrongTypes/badArray.gltf",
            format,
            &["expected a sequence", "line 44"],
        ),
        (
            "wrongTypes/badExtension.gltf",
            format,
            &["Not an object", "TextureTransform"],
        ),
        (
            "wrongTypes/badNumber.gltf",
            format,
            &["not a number", "f32"],
        ),
        ("wrongTypes/badObject.gltf", format, &["not an object"]),
        (
            "wrongTypes/badString.gltf",
            format,
            &["42", "expected a string"],
        ),
        ("wrongTypes/badUint.gltf", format, &["-1"]),
        (
            "BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb",
            format,
            &["POSITION (accessor 2)", "vertex 0 is not finite"],
        ),
        (
            "draco/2CylinderEngine.gltf",
            |e| matches!(e, Error::Unsupported(_)),
            &["KHR_draco_mesh_compression"],
        ),
        (
            "BoxTextured-glTF-techniqueWebGL/BoxTextured.gltf",
            |e| matches!(e, Error::Unsupported(_)),
            &["KHR_technique_webgl"],
        ),
    ];
    for &(file, kind, needles) in cases {
        let e = match load(&dir, file) {
            Ok(a) => panic!(
                "{file}: loaded {} triangles, expected an error",
                a.triangle_count()
            ),
            Err(e) => e,
        };
        assert!(kind(&e), "{file}: wrong kind of error: {e}");
        let msg = e.to_string();
        for n in needles {
            assert!(msg.contains(n), "{file}: '{msg}' does not name '{n}'");
        }
    }
}

#[test]
fn every_file_in_the_collection_loads_or_fails_cleanly() {
    let Some(dir) = artefact_support::data_dir() else {
        return;
    };
    let mut files = Vec::new();
    let mut stack = vec![dir.clone()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let p = entry.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|e| e == "gltf" || e == "glb") {
                files.push(p);
            }
        }
    }
    assert!(files.len() >= 40, "{}", files.len());
    for f in files {
        let result = std::panic::catch_unwind(|| {
            Artefact::from_path(&f, &LoadOptions::default()).map(|a| a.triangle_count())
        });
        match result {
            Err(_) => panic!("{}: panicked", f.display()),
            Ok(Err(e)) => assert!(!e.to_string().is_empty()),
            Ok(Ok(_)) => {}
        }
    }
}
