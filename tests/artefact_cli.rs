//! `parallax inspect`: prints what a model holds; exits 1 naming the problem for a broken one.
#![cfg(all(feature = "gltf", feature = "cli"))]

mod artefact_support;

use std::process::Command;

#[test]
fn inspect_prints_counts_materials_textures_and_bounds() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("box.glb");
    std::fs::write(
        &path,
        artefact_support::textured_box(0.5, [0.0, 1.0, 0.0]).glb(),
    )
    .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_parallax"))
        .args(["inspect", "--quiet"])
        .arg(&path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    for needle in [
        "1 primitives, 12 triangles, 24 vertices",
        "min (-0.500000, 0.500000, -0.500000) max (0.500000, 1.500000, 0.500000)",
        "mesh 0 'Box' primitive 0 at node 0: 12 triangles",
        "Painted",
        "alpha MASK 0.3",
        "base colour texture 0 (TEXCOORD_0)",
        "2x2 wrap ClampToEdge/MirroredRepeat",
        "warnings: 0",
    ] {
        assert!(text.contains(needle), "missing '{needle}' in:\n{text}");
    }
}

#[test]
fn inspect_fails_with_the_loader_message_for_a_broken_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cycle.gltf");
    std::fs::write(
        &path,
        br#"{"asset":{"version":"2.0"},"scenes":[{"nodes":[0]}],
            "nodes":[{"children":[1]},{"children":[0]}]}"#,
    )
    .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_parallax"))
        .args(["inspect", "--quiet"])
        .arg(&path)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("node cycle: 0 → 1 → 0"), "{err}");
}
