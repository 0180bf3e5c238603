//! `parallax synth` end to end: a tiny render with an inserted object, and bad input.
#![cfg(feature = "cli")]

use std::process::Command;

fn parallax() -> Command {
    Command::new(env!("CARGO_BIN_EXE_parallax"))
}

#[test]
fn synth_writes_the_middlebury_layout_and_composites() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("report.json");
    let out = parallax()
        .args([
            "synth",
            "--scene",
            "two-lights",
            "--width",
            "32",
            "--spp",
            "2",
            "--quiet",
        ])
        .args([
            "--insert",
            "box@0.5,0,-1,1,30",
            "--insert",
            "sphere@-0.3,0.75,-1.8",
        ])
        .arg("--out-dir")
        .arg(dir.path())
        .arg("--report")
        .arg(&report)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for name in [
        "im0.png",
        "im1.png",
        "calib.txt",
        "disp0GT.pfm",
        "mask0nocc.png",
        "depth0GT.pfm",
        "normals0GT.exr",
        "shadow0GT.exr",
        "lights.json",
        "composite_gt.png",
        "composite_gt.exr",
        "background_gt.exr",
        "ratio_gt.exr",
        "mask_gt.png",
    ] {
        assert!(dir.path().join(name).is_file(), "{name} missing");
    }
    let calib =
        parallax::camera::StereoCalibration::load_middlebury(dir.path().join("calib.txt")).unwrap();
    assert_eq!(calib.cx, 16.0);
    let lights: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("lights.json")).unwrap())
            .unwrap();
    assert_eq!(lights["lights"].as_array().unwrap().len(), 2);
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(report).unwrap()).unwrap();
    let names: Vec<&str> = report["stages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["name"].as_str().unwrap())
        .collect();
    assert!(names.contains(&"synth.render") && names.contains(&"synth.composite"));
    let mask = parallax::image::Image::load(
        dir.path().join("mask_gt.png"),
        &parallax::image::ImageLimits::default(),
    )
    .unwrap();
    assert!(
        mask.as_bytes().contains(&255),
        "inserted objects not in the mask"
    );
}

#[test]
fn synth_rejects_bad_input_with_a_message() {
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&[&str], &str); 4] = [
        (&["--scene", "kitchen"], "built-in scene"),
        (
            &["--scene", "room", "--insert", "model.glb@0,0,0"],
            "model.glb",
        ),
        (
            &["--scene", "room", "--insert", "sphere@0,0"],
            "3 to 5 numbers",
        ),
        (&["--scene", "room", "--spp", "0"], "samples per pixel"),
    ];
    for (args, message) in cases {
        let out = parallax()
            .arg("synth")
            .args(args)
            .arg("--out-dir")
            .arg(dir.path())
            .arg("--quiet")
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(1), "{args:?}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains(message), "{args:?}: {stderr}");
    }
}
