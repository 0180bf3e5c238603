//! `parallax demo`, `parallax composite --debug-dir` and `parallax eval composite`: the whole
//! pipeline from the command line on synthetic scenes, checked through the files they write.

#![cfg(all(feature = "gpu", feature = "gltf"))]

use std::path::Path;
use std::process::Command;

use parallax::image::{Image, Raster};

fn parallax() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_parallax"));
    c.env("XDG_RUNTIME_DIR", std::env::temp_dir());
    c
}

fn run(args: &[&str], dir: &Path) {
    let out = parallax().current_dir(dir).args(args).output().unwrap();
    assert!(
        out.status.success(),
        "parallax {args:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn load(path: &Path) -> Raster<[f32; 3]> {
    Image::load(path, &Default::default())
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_linear_rgb()
}

fn json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn stage_status(report: &serde_json::Value, name: &str) -> Vec<String> {
    report["stages"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|s| s["name"] == name)
        .map(|s| s["status"].as_str().unwrap().to_string())
        .collect()
}

#[test]
fn demo_renders_two_objects_into_the_synthetic_room_with_every_intermediate_product() {
    let dir = tempfile::tempdir().unwrap();
    run(
        &[
            "demo",
            "--quiet",
            "--out-dir",
            "demo",
            "--width",
            "256",
            "--spp",
            "4",
        ],
        dir.path(),
    );
    let out = dir.path().join("demo");
    for file in [
        "composite.png",
        "mask.png",
        "shadow_ratio.png",
        "disparity.pfm",
        "disparity.png",
        "depth.pfm",
        "normals.png",
        "surfaces.png",
        "lights.png",
        "pair/im0.png",
        "pair/im1.png",
        "pair/calib.txt",
    ] {
        assert!(out.join(file).is_file(), "demo wrote no {file}");
    }
    let photo = load(&out.join("pair/im0.png"));
    let composite = load(&out.join("composite.png"));
    let mask = load(&out.join("mask.png"));
    assert_eq!(
        (photo.width(), photo.height()),
        (composite.width(), composite.height())
    );
    // Both objects cover pixels, the composite differs from the photo there, and nowhere is it
    // brighter than the photo away from the objects (their shadows only darken).
    let covered: Vec<usize> = (0..mask.len())
        .filter(|&i| mask.pixels()[i][0] > 0.9)
        .collect();
    assert!(covered.len() > 100, "{} covered pixels", covered.len());
    let changed = covered
        .iter()
        .filter(|&&i| {
            let (a, b) = (photo.pixels()[i], composite.pixels()[i]);
            (0..3).any(|k| (a[k] - b[k]).abs() > 0.02)
        })
        .count();
    assert!(
        changed * 2 > covered.len(),
        "{changed} of {} changed",
        covered.len()
    );
    for (i, (p, c)) in photo.pixels().iter().zip(composite.pixels()).enumerate() {
        if mask.pixels()[i][0] < 0.01 {
            assert!(
                (0..3).all(|k| c[k] <= p[k] + 0.02),
                "pixel {i}: {c:?} > {p:?}"
            );
        }
    }
    let report = json(&out.join("report.json"));
    assert_eq!(stage_status(&report, "stereo")[0], "computed");
    assert_eq!(stage_status(&report, "render")[0], "computed");
    let surfaces = json(&out.join("surfaces.json"));
    assert!(surfaces["up"].as_array().unwrap().len() == 3);
    let lights = json(&out.join("lights.json"));
    assert!(!lights.as_array().unwrap().is_empty());
}

#[test]
fn composite_debug_dir_holds_the_products_and_moving_nothing_recomputes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    run(
        &[
            "synth",
            "--quiet",
            "--scene",
            "room",
            "--width",
            "192",
            "--spp",
            "4",
            "--out-dir",
            "room",
        ],
        dir.path(),
    );
    run(
        &[
            "composite",
            "--quiet",
            "--left",
            "room/im0.png",
            "--right",
            "room/im1.png",
            "--calib",
            "room/calib.txt",
            "--insert",
            "sphere@96,110,0.25",
            "--out",
            "c.png",
            "--light",
            "directional@0.2,-1,-0.4@3,3,2.8@1.5",
            "--debug-dir",
            "debug",
            "--report",
            "r.json",
        ],
        dir.path(),
    );
    let debug = dir.path().join("debug");
    for file in [
        "disparity.pfm",
        "depth.pfm",
        "normals.png",
        "surfaces.json",
        "surfaces.png",
        "lights.json",
        "lights.png",
        "shadow_ratio.png",
        "mask.png",
        "composite.png",
    ] {
        assert!(debug.join(file).is_file(), "debug dir has no {file}");
    }
    assert_eq!(
        load(&debug.join("composite.png")),
        load(&dir.path().join("c.png"))
    );
    let depth = Raster::<f32>::read_pfm(debug.join("depth.pfm"), &Default::default()).unwrap();
    assert!(depth.pixels().iter().all(|z| z.is_finite() && *z > 0.0));
    // The debug outputs reuse what the render computed: stereo ran once.
    let report = json(&dir.path().join("r.json"));
    let stereo = stage_status(&report, "stereo");
    assert_eq!(
        stereo.iter().filter(|s| *s == "computed").count(),
        1,
        "{stereo:?}"
    );
    // The host's light replaced the estimate: the render skipped the lighting stage.
    assert_eq!(stage_status(&report, "lighting")[0], "skipped");
    let lights = json(&debug.join("lights.json"));
    let lights = lights.as_array().unwrap();
    assert_eq!(lights.len(), 1, "{lights:?}");
    assert_eq!(lights[0]["kind"], "directional");
    assert_eq!(lights[0]["size"], 1.5);
    for (light, needle) in [
        ("spot@1,2,3@1,1,1", "unknown kind"),
        ("point@1,2@1,1,1", "three values"),
        ("area@0,1,-2@1,1,1", "number of @ groups"),
        ("directional@0,-1,0@1,nan,1", "finite"),
    ] {
        let out = parallax()
            .current_dir(dir.path())
            .args([
                "composite",
                "--quiet",
                "--left",
                "room/im0.png",
                "--right",
                "room/im1.png",
                "--calib",
                "room/calib.txt",
                "--insert",
                "box@96,110",
                "--light",
                light,
                "--out",
                "bad.png",
            ])
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(1), "{light}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            stderr.contains(needle) && stderr.contains("--light"),
            "{light}: {stderr}"
        );
    }
}

#[test]
fn a_debug_dir_that_cannot_be_written_fails_after_the_warnings_of_the_run() {
    let dir = tempfile::tempdir().unwrap();
    run(
        &[
            "synth",
            "--quiet",
            "--scene",
            "room",
            "--width",
            "128",
            "--spp",
            "4",
            "--out-dir",
            "room",
        ],
        dir.path(),
    );
    std::fs::write(dir.path().join("blocker"), b"a file").unwrap();
    let composite = |debug_dir: &str, report: &str| {
        parallax()
            .current_dir(dir.path())
            .args([
                "composite",
                "--left",
                "room/im0.png",
                "--right",
                "room/im1.png",
                "--calib",
                "room/calib.txt",
                "--insert",
                "box@64,74",
                "--out",
                "c.png",
                "--debug-dir",
                debug_dir,
                "--report",
                report,
            ])
            .output()
            .unwrap()
    };
    // The same run with a directory it can write: the warnings it gathers.
    let ok = composite("debug", "r.json");
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    let report = json(&dir.path().join("r.json"));
    let warnings: Vec<&str> = report["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap())
        .collect();

    let failed = composite("blocker/debug", "r2.json");
    assert_eq!(failed.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&failed.stderr);
    assert!(
        stderr.contains("parallax: error:") && stderr.contains("blocker/debug"),
        "{stderr}"
    );
    let error_at = stderr.find("parallax: error:").unwrap();
    for warning in warnings {
        let at = stderr.find(warning);
        assert!(
            at.is_some_and(|at| at < error_at),
            "{warning:?} not before the error: {stderr}"
        );
    }
}

#[test]
fn eval_composite_measures_both_input_kinds_and_writes_table_json_and_plot() {
    let dir = tempfile::tempdir().unwrap();
    run(
        &[
            "eval",
            "composite",
            "--quiet",
            "--scene",
            "room",
            "--width",
            "128",
            "--spp",
            "4",
            "--configs",
            "quick",
            "--max-triangles",
            "300",
            "--out",
            "ev",
        ],
        dir.path(),
    );
    let ev = dir.path().join("ev");
    let report = json(&ev.join("composite.json"));
    let rows = report["rows"].as_array().unwrap();
    // Four shadow modes, each with true and with estimated inputs.
    assert_eq!(rows.len(), 8);
    for r in rows {
        let e = &r["errors"];
        for region in ["image", "artefact", "shadow", "affected"] {
            let mae = e[region]["mae"].as_f64().unwrap();
            assert!(mae.is_finite() && mae >= 0.0, "{r}");
        }
        assert!(r["render_ms"].as_f64().unwrap() > 0.0);
        if r["inputs"] == "true" {
            // With the true depth and lights only the objects and their shadows can differ.
            let psnr = e["image"]["psnr"].as_f64().unwrap();
            assert!(psnr > 30.0, "{r}");
        }
    }
    assert!(report["scenes"][0]["reference_seconds"].as_f64().unwrap() > 0.0);
    // The full grid and the one budget asked for. A noisy stereo mesh cut into many pieces may
    // stay above a budget (`mesh::simplify` refuses collapses that tear it), but it shrinks.
    let budgets = report["budgets"].as_array().unwrap();
    assert_eq!(budgets.len(), 2, "{budgets:?}");
    assert!(budgets[0]["max_triangles"].is_null());
    assert_eq!(budgets[1]["max_triangles"], 300);
    assert_eq!(budgets[1]["config"], "pbr esm 1024 r2");
    let triangles = |b: &serde_json::Value| b["triangles"].as_u64().unwrap();
    assert!(
        triangles(&budgets[1]) < triangles(&budgets[0]) / 2,
        "{budgets:?}"
    );
    for b in budgets {
        let psnr = b["errors"]["image"]["psnr"].as_f64().unwrap();
        assert!(psnr.is_finite() && psnr > 10.0, "{b}");
    }
    let md = std::fs::read_to_string(ev.join("composite.md")).unwrap();
    assert!(md.contains("| true | pbr esm 1024 r2 |") && md.contains("| estimated |"));
    assert!(
        md.contains("| full grid |") && md.contains("| 300 |"),
        "{md}"
    );
    let plot = load(&ev.join("composite_error_vs_time.png"));
    assert_eq!((plot.width(), plot.height()), (640, 480));
    assert!(ev.join("room_truth.png").is_file() && ev.join("room_estimated.png").is_file());
}
