//! `parallax eval reconstruction` on `room` at a tiny size: the table has every column, the JSON
//! holds finite figures in their ranges, and the true floor and table were found in the render.

use std::process::Command;

const COLUMNS: [&str; 13] = [
    "scene",
    "render noise (median σ/L)",
    "depth rel. err. median / p90",
    "mesh rel. err. median / p90",
    "mesh coverage",
    "normal err. median / p90, all pixels (°)",
    "floor normal err. median (°)",
    "table normal err. median (°)",
    "floor plane normal err. (°)",
    "table plane normal err. (°)",
    "up err. (°)",
    "floor placement height err. (% dist.)",
    "table placement height err. (% dist.)",
];

#[test]
fn room_at_tiny_size_gives_the_table_and_finite_figures() {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_parallax"))
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .args(["eval", "reconstruction", "--scene", "room"])
        .args(["--width", "96", "--height", "72", "--spp", "2", "--quiet"])
        .arg("--out")
        .arg(dir.path())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let header = format!("| {} |", COLUMNS.join(" | "));
    assert!(stdout.contains(&header), "no table header in:\n{stdout}");
    let md = std::fs::read_to_string(dir.path().join("reconstruction.md")).unwrap();
    assert!(md.contains(&header));
    let row = md.lines().find(|l| l.starts_with("| room |")).unwrap();
    assert_eq!(row.matches('|').count(), COLUMNS.len() + 1, "{row}");

    let json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("reconstruction.json")).unwrap(),
    )
    .unwrap();
    let r = &json[0];
    assert_eq!(r["scene"], "room");
    // Two samples per pixel: a noisy render, but a finite, positive noise figure.
    let noise = r["render_noise"].as_f64().unwrap();
    assert!(noise > 0.0 && noise < 10.0, "render noise {noise}: {r}");
    for key in ["depth_error", "mesh_error", "normal_error_deg"] {
        let (m, p) = (
            r[key]["median"].as_f64().unwrap(),
            r[key]["p90"].as_f64().unwrap(),
        );
        assert!(
            m.is_finite() && p.is_finite() && 0.0 <= m && m <= p,
            "{key}: {r}"
        );
    }
    let coverage = r["mesh_coverage"].as_f64().unwrap();
    assert!(coverage > 0.0 && coverage <= 1.0, "{r}");
    let up = r["up_error_deg"].as_f64().unwrap();
    assert!((0.0..=180.0).contains(&up), "{r}");
    // The room has a floor and a table top; both are seen from the rig.
    let planes = r["planes"].as_array().unwrap();
    let names: Vec<&str> = planes
        .iter()
        .map(|p| p["plane"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["floor", "table"]);
    for p in planes {
        assert!(p["pixels"].as_u64().unwrap() > 0, "{p}");
        let n = p["normal_error_deg"]["median"].as_f64().unwrap();
        assert!((0.0..=180.0).contains(&n), "{p}");
        if let Some(h) = p["placement_height_error"].as_f64() {
            assert!(h.is_finite(), "{p}");
        }
    }
}

#[test]
fn options_are_scored_on_the_same_render_and_bad_ones_are_refused_before_it() {
    let dir = tempfile::tempdir().unwrap();
    let run = |options: &[&str], out: &std::path::Path| {
        let mut command = Command::new(env!("CARGO_BIN_EXE_parallax"));
        command
            .env("XDG_RUNTIME_DIR", std::env::temp_dir())
            .args(["eval", "reconstruction", "--scene", "room"])
            .args(["--width", "96", "--height", "72", "--spp", "2", "--quiet"])
            .arg("--out")
            .arg(out);
        for o in options {
            command.args(["--options", o]);
        }
        command.output().unwrap()
    };
    let out = run(&[r#"{"smoothing_passes": 0}"#], dir.path());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let md = std::fs::read_to_string(dir.path().join("reconstruction.md")).unwrap();
    assert!(
        md.contains("| room |") && md.contains("| room (options 1) |"),
        "{md}"
    );
    assert!(
        md.contains(r#"- options 1: `{"smoothing_passes": 0}`"#),
        "{md}"
    );
    let json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("reconstruction.json")).unwrap(),
    )
    .unwrap();
    let (default, unsmoothed) = (&json[0], &json[1]);
    assert_eq!(default["options"], serde_json::Value::Null);
    assert_eq!(unsmoothed["options"], r#"{"smoothing_passes": 0}"#);
    // One render: the same noise figure; other options: another depth map.
    assert_eq!(default["render_noise"], unsmoothed["render_noise"]);
    assert_ne!(
        default["depth_error"], unsmoothed["depth_error"],
        "the options were not applied"
    );

    // Refused before rendering, naming the option: the output folder, made before the first
    // render, is not made.
    let refused_out = dir.path().join("refused");
    let out = run(&[r#"{"p1": 500, "p2": 10}"#], &refused_out);
    assert!(!out.status.success());
    assert!(
        !refused_out.exists(),
        "the refusal came after the output folder was made"
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("--options") && stderr.contains("p1"),
        "{stderr}"
    );
}
