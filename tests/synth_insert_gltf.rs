//! `parallax synth --insert FILE.glb@…`: a glTF model built in code is inserted into a reference
//! scene and shows up in the ground-truth composite.
#![cfg(all(feature = "cli", feature = "gltf"))]

mod artefact_support;

use std::process::Command;

#[test]
fn synth_inserts_a_glb_model() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("box.glb");
    std::fs::write(&model, artefact_support::textured_box(0.5, [0.0; 3]).glb()).unwrap();
    let out_dir = dir.path().join("out");
    let out = Command::new(env!("CARGO_BIN_EXE_parallax"))
        .args([
            "synth",
            "--scene",
            "two-lights",
            "--width",
            "32",
            "--spp",
            "2",
        ])
        .arg("--insert")
        .arg(format!("{}@0.5,0,-1,0.3,30", model.display()))
        .arg("--out-dir")
        .arg(&out_dir)
        .arg("--quiet")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mask = parallax::image::Image::load(
        out_dir.join("mask_gt.png"),
        &parallax::image::ImageLimits::default(),
    )
    .unwrap();
    assert!(
        mask.as_bytes().contains(&255),
        "the inserted model is not in the mask"
    );
    // A broken model is refused with the loader's message.
    let broken = dir.path().join("broken.glb");
    std::fs::write(&broken, b"glTF\x02\0\0\0").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_parallax"))
        .args([
            "synth",
            "--scene",
            "two-lights",
            "--width",
            "32",
            "--spp",
            "1",
        ])
        .arg("--insert")
        .arg(format!("{}@0,0,0", broken.display()))
        .arg("--out-dir")
        .arg(&out_dir)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("GLB") || stderr.contains("glb"), "{stderr}");
}
