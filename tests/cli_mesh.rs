//! `parallax mesh` and `parallax surfaces` through the Scene: from a synthetic stereo pair (stereo
//! runs) and from a depth PFM (the host-depth path: stereo skipped), checked via the outputs and
//! the `--report` stages.

use std::path::Path;
use std::process::Command;

use parallax::image::{Image, PixelFormat, Raster};

fn parallax() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_parallax"));
    c.env("XDG_RUNTIME_DIR", std::env::temp_dir());
    c
}

fn run(args: &[&str], dir: &Path) -> serde_json::Value {
    let out = parallax().current_dir(dir).args(args).output().unwrap();
    assert!(
        out.status.success(),
        "parallax {args:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report = std::fs::read_to_string(dir.join("r.json")).unwrap();
    serde_json::from_str(&report).unwrap()
}

fn stage<'a>(report: &'a serde_json::Value, name: &str) -> &'a serde_json::Value {
    report["stages"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["name"] == name)
        .unwrap_or_else(|| panic!("no stage {name} in {report}"))
}

/// A random texture, and the right view seeing it `shift` px further left (disparity `shift`).
fn write_pair(dir: &Path, w: u32, h: u32, shift: i64) {
    let texture = |x: i64, y: i64| -> u8 {
        let mut v = (x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663)) as u64;
        v ^= v >> 13;
        v = v.wrapping_mul(0x5bd1_e995);
        (v >> 24) as u8
    };
    for (name, offset) in [("l.png", 0), ("r.png", shift)] {
        let data = (0..h as i64)
            .flat_map(|y| (0..w as i64).map(move |x| (x, y)))
            .map(|(x, y)| texture(x + offset, y))
            .collect();
        Image::from_bytes(w, h, PixelFormat::Gray8, data)
            .unwrap()
            .save_png(dir.join(name))
            .unwrap();
    }
}

/// `z.pfm`: a floor 1 m below a camera of f = 60 px (64×48; give `--focal 60`) and a wall at 6 m.
/// Returns the size.
fn write_floor_and_wall(dir: &Path) -> (usize, usize) {
    let (w, h, f) = (64usize, 48usize, 60.0f32);
    let depth = Raster::from_fn(w, h, |_, y| {
        let dy = -((y as f32 + 0.5) - h as f32 / 2.0) / f;
        if dy < 0.0 {
            (-1.0 / dy).min(6.0)
        } else {
            6.0
        }
    });
    depth.write_pfm(dir.join("z.pfm")).unwrap();
    (w, h)
}

/// The face count in a PLY header.
fn ply_faces(path: &Path) -> usize {
    let ply = std::fs::read(path).unwrap();
    let header = String::from_utf8_lossy(&ply[..ply.len().min(400)]).to_string();
    assert!(header.starts_with("ply"), "{header}");
    header
        .lines()
        .find_map(|l| l.strip_prefix("element face "))
        .unwrap()
        .trim()
        .parse()
        .unwrap()
}

#[test]
fn mesh_from_a_stereo_pair_runs_stereo_in_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    write_pair(dir.path(), 96, 48, 6);
    let args = [
        "mesh",
        "--quiet",
        "--left",
        "l.png",
        "--right",
        "r.png",
        "--preset",
        "fast",
        "--max-disparity",
        "16",
        "--focal",
        "600",
        "--baseline",
        "0.1",
        "--out",
        "m.ply",
        "--report",
        "r.json",
    ];
    let report = run(&args, dir.path());
    for name in [
        "stereo",
        "depth",
        "mesh.grid",
        "surfaces",
        "mesh.snap",
        "mesh",
        "mesh.export",
    ] {
        assert_eq!(
            stage(&report, name)["status"],
            "computed",
            "{name}: {report}"
        );
    }
    assert_eq!(stage(&report, "mesh.simplify")["status"], "skipped");
    let full = ply_faces(&dir.path().join("m.ply"));
    // The grid of a 96×48 view has at most 2·95·47 triangles.
    assert!(full > 4000 && full <= 2 * 95 * 47, "{full}");

    let mut budget = args.to_vec();
    budget.extend(["--max-triangles", "500"]);
    let report = run(&budget, dir.path());
    assert_eq!(stage(&report, "mesh.simplify")["status"], "computed");
    // The budget is met where the topology allows; stereo noise leaves a few cut pieces.
    let simplified = ply_faces(&dir.path().join("m.ply"));
    assert!(
        simplified > 0 && simplified < full / 4,
        "{simplified} of {full}"
    );

    // Each vertex's own normal: no snap, and no surfaces needed.
    let mut own_normals = args.to_vec();
    own_normals.push("--no-snap");
    let report = run(&own_normals, dir.path());
    assert_eq!(stage(&report, "mesh.snap")["status"], "skipped");
    let stages = report["stages"].as_array().unwrap();
    assert!(!stages.iter().any(|s| s["name"] == "surfaces"), "{report}");

    // Missing --right is a usage error.
    let out = parallax()
        .current_dir(dir.path())
        .args(["mesh", "--left", "l.png", "--out", "m.ply"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn surfaces_from_host_depth_skip_stereo_and_find_the_floor() {
    let dir = tempfile::tempdir().unwrap();
    write_floor_and_wall(dir.path());
    let report = run(
        &[
            "surfaces",
            "--quiet",
            "--depth",
            "z.pfm",
            "--focal",
            "60",
            "--out",
            "s.json",
            "--out-preview",
            "p.png",
            "--report",
            "r.json",
        ],
        dir.path(),
    );
    let stereo = stage(&report, "stereo");
    assert_eq!(stereo["status"], "skipped");
    assert_eq!(stereo["why"], "host depth given");
    assert_eq!(stage(&report, "surfaces")["status"], "computed");
    assert!(dir.path().join("p.png").exists());
    let found: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("s.json")).unwrap()).unwrap();
    let floor = found["surfaces"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["kind"] == "horizontal")
        .unwrap_or_else(|| panic!("no horizontal surface: {found}"));
    assert!(
        (floor["offset"].as_f64().unwrap() + 1.0).abs() < 0.02,
        "{floor}"
    );
    assert!(found["up"][1].as_f64().unwrap() > 0.99);
    assert_eq!(found["up_source"], "planes");

    // An IMU's up (pitched 45°) replaces the planes'; the floor is then not horizontal.
    run(
        &[
            "surfaces", "--quiet", "--depth", "z.pfm", "--focal", "60", "--up", "0,2,-2", "--out",
            "s.json", "--report", "r.json",
        ],
        dir.path(),
    );
    let found: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("s.json")).unwrap()).unwrap();
    assert_eq!(found["up_source"], "host");
    assert!(
        (found["up"][2].as_f64().unwrap() + std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-3,
        "{found}"
    );
    assert!(found["surfaces"]
        .as_array()
        .unwrap()
        .iter()
        .all(|s| s["kind"] != "horizontal"));

    // The same depth as a mesh (GLB), host path again.
    let report = run(
        &[
            "mesh", "--quiet", "--depth", "z.pfm", "--focal", "60", "--out", "m.glb", "--report",
            "r.json",
        ],
        dir.path(),
    );
    assert_eq!(stage(&report, "stereo")["status"], "skipped");
    assert_eq!(stage(&report, "mesh")["status"], "computed");
    let glb = std::fs::read(dir.path().join("m.glb")).unwrap();
    assert_eq!(&glb[..4], b"glTF");
}

#[test]
fn composite_without_artefacts_is_the_photo_and_runs_no_stereo_and_bad_inserts_are_named() {
    let dir = tempfile::tempdir().unwrap();
    write_pair(dir.path(), 96, 48, 6);
    let base = [
        "composite",
        "--quiet",
        "--left",
        "l.png",
        "--right",
        "r.png",
        "--focal",
        "60",
        "--baseline",
        "0.1",
        "--out",
        "c.png",
        "--report",
        "r.json",
    ];
    let report = run(&base, dir.path());
    assert_eq!(stage(&report, "render")["status"], "skipped");
    assert!(report["stages"]
        .as_array()
        .unwrap()
        .iter()
        .all(|s| s["name"] != "stereo"));
    let photo = Image::load(dir.path().join("l.png"), &Default::default()).unwrap();
    let composite = Image::load(dir.path().join("c.png"), &Default::default()).unwrap();
    assert_eq!(photo.to_linear_rgb(), composite.to_linear_rgb());

    // The wall is 1 m away: a box stands against the pixel's surface and covers it.
    let mut with_box = base.to_vec();
    with_box.extend(["--insert", "box@48,24,0.2", "--out-mask", "m.png"]);
    let report = run(&with_box, dir.path());
    assert_eq!(stage(&report, "render")["status"], "computed");
    let mask = Image::load(dir.path().join("m.png"), &Default::default()).unwrap();
    let covered: Raster<[f32; 3]> = mask.to_linear_rgb();
    assert!(covered.get(48, 24)[0] > 0.9, "{:?}", covered.get(48, 24));

    for (insert, needle) in [
        ("box@1,2,3,4,5", "expected WHAT@X,Y"),
        ("teapot@10,10", "teapot"),
        ("box@nan,1", "expected WHAT@X,Y"),
    ] {
        let mut args = base.to_vec();
        args.extend(["--insert", insert]);
        let out = parallax()
            .current_dir(dir.path())
            .args(&args)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(1), "{insert}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains(needle), "{insert}: {stderr}");
    }
}

#[test]
fn lights_and_composites_from_host_depth_and_a_photo_and_the_named_insertion_point() {
    let dir = tempfile::tempdir().unwrap();
    // The floor-and-wall depth, and a photo: a bright wall over a grey floor.
    let (w, h) = write_floor_and_wall(dir.path());
    let photo: Vec<u8> = (0..h)
        .flat_map(|y| (0..w).map(move |_| if y < h / 2 { 220 } else { 90 }))
        .collect();
    Image::from_bytes(w as u32, h as u32, PixelFormat::Gray8, photo)
        .unwrap()
        .save_png(dir.path().join("photo.png"))
        .unwrap();
    // Every command below reads this host input.
    let host = |command: &'static str, rest: &[&'static str]| -> Vec<&'static str> {
        let mut args = vec![
            command,
            "--depth",
            "z.pfm",
            "--focal",
            "60",
            "--image",
            "photo.png",
        ];
        args.extend_from_slice(rest);
        args
    };
    let lights = |point: Option<&'static str>| -> serde_json::Value {
        let mut args = host(
            "lights",
            &["--quiet", "--out", "l.json", "--report", "r.json"],
        );
        if let Some(p) = point {
            args.extend(["--insertion-point", p]);
        }
        run(&args, dir.path());
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("l.json")).unwrap()).unwrap()
    };
    let default = lights(None);
    let near_wall = lights(Some("0,-0.5,-5.5"));
    let point: Vec<f64> = near_wall["insertion_point"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert_eq!(point, [0.0, -0.5, -5.5]);
    // Default: 2 cm above the floor's median point; next to the bright wall the SH differs.
    assert!(
        (default["insertion_point"][1].as_f64().unwrap() + 0.98).abs() < 0.01,
        "{default}"
    );
    let sh = |v: &serde_json::Value| v["sh9"][0].as_f64().unwrap();
    assert!(
        (sh(&default) - sh(&near_wall)).abs() > 1e-3,
        "{default} {near_wall}"
    );

    // The same host depth and photo take a composite: an object on the floor, no stereo.
    let report = run(
        &host(
            "composite",
            &[
                "--quiet",
                "--insert",
                "sphere@32,40,0.3",
                "--out",
                "c.png",
                "--report",
                "r.json",
            ],
        ),
        dir.path(),
    );
    assert_eq!(stage(&report, "stereo")["status"], "skipped");
    assert_eq!(stage(&report, "render")["status"], "computed");
    let composite = Image::load(dir.path().join("c.png"), &Default::default()).unwrap();
    let photo = Image::load(dir.path().join("photo.png"), &Default::default()).unwrap();
    assert_ne!(composite.to_linear_rgb(), photo.to_linear_rgb());

    let out = parallax()
        .current_dir(dir.path())
        .args(host(
            "lights",
            &["--out", "l.json", "--insertion-point", "0,1"],
        ))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("X,Y,Z"));
}

#[test]
fn a_flat_pair_fails_with_the_warning_that_says_why() {
    let dir = tempfile::tempdir().unwrap();
    let flat = Image::from_bytes(64, 48, PixelFormat::Gray8, vec![90; 64 * 48]).unwrap();
    for name in ["l.png", "r.png"] {
        flat.save_png(dir.path().join(name)).unwrap();
    }
    let mut commands = vec![
        "mesh --out m.ply",
        "surfaces --out-preview s.png",
        "lights --out l.json",
    ];
    // Fails placing the box, before anything is rendered.
    #[cfg(all(feature = "gpu", feature = "gltf"))]
    commands.push("composite --insert box@32,24 --out c.png");
    for command in commands {
        let args: Vec<&str> = command
            .split(' ')
            .chain(["--left", "l.png", "--right", "r.png"])
            .collect();
        let out = parallax()
            .current_dir(dir.path())
            .args(&args)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(stderr.contains("parallax: error:"), "{args:?}: {stderr}");
        assert!(stderr.contains("nothing to match"), "{args:?}: {stderr}");
        // Quiet keeps the error alone.
        let quiet = parallax()
            .current_dir(dir.path())
            .args(&args)
            .arg("-q")
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&quiet.stderr);
        assert!(!stderr.contains("warning"), "{args:?}: {stderr}");
    }
}
