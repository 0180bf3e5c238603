//! The command-line tool's shared plumbing: `--report`, exit codes.

use std::process::Command;

fn parallax() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_parallax"));
    c.env("XDG_RUNTIME_DIR", std::env::temp_dir());
    c
}

#[test]
fn info_prints_version_and_writes_a_report() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("r.json");
    let out = parallax()
        .args(["info", "--quiet", "--report"])
        .arg(&report)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains(env!("CARGO_PKG_VERSION")), "{stdout}");
    assert!(stdout.contains("GPU adapters"), "{stdout}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(json["version"], env!("CARGO_PKG_VERSION"));
    for key in ["stages", "warnings", "peak_rss_mb", "total_ms"] {
        assert!(json.get(key).is_some(), "report lacks {key}: {json}");
    }
    if cfg!(feature = "gpu") {
        assert_eq!(json["stages"][0]["name"], "gpu.enumerate");
        assert_eq!(json["stages"][0]["status"], "computed");
    }
}

#[test]
fn bad_usage_exits_2_and_unwritable_report_exits_1() {
    let out = parallax()
        .args(["info", "--no-such-flag"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let out = parallax()
        .args(["info", "--quiet", "--report", "/nonexistent-dir/r.json"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("/nonexistent-dir/r.json"), "{stderr}");
}
