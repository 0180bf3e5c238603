//! What the host-language tests (C++, C#, CMake) share: the built library, a synthetic stereo
//! scene with ground truth written as files, a box GLB, and running a program (under
//! `PARALLAX_FFI_WRAPPER`, e.g. valgrind, when set).

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use parallax::image::Image;
use parallax::reference::{self, RenderOptions, SampleBudget};

/// `target/<profile>/deps`, where `cargo test` puts the `libparallax.so` of this run's features.
pub fn library_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    exe.parent().expect("deps folder").to_path_buf()
}

/// The crate root.
pub fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Whitespace-separated words of an environment variable.
pub fn split_env(name: &str) -> Vec<String> {
    std::env::var(name)
        .map(|v| v.split_whitespace().map(str::to_string).collect())
        .unwrap_or_default()
}

/// A synthetic stereo pair with its calibration and ground truth, as files.
pub struct Synthetic {
    pub left: PathBuf,
    pub right: PathBuf,
    pub glb: PathBuf,
    pub width: u32,
    pub height: u32,
    pub focal_px: f64,
    pub baseline_m: f64,
    /// True depth (metres) and disparity (pixels) at pixel (width/2, height/2).
    pub depth_centre_m: f32,
    pub disparity_centre_px: f32,
    /// True depth in metres, row-major.
    pub depth: parallax::image::Raster<f32>,
}

impl Synthetic {
    /// The true 3D point (camera frame, metres) seen at continuous pixel (x, y) (DESIGN.md:
    /// principal point at the image centre for the reference renderer).
    pub fn point_at(&self, x: f32, y: f32) -> [f32; 3] {
        let z = *self.depth.get(x as usize, y as usize);
        assert!(z.is_finite(), "no true depth at ({x}, {y})");
        let f = self.focal_px as f32;
        let (cx, cy) = (self.width as f32 / 2.0, self.height as f32 / 2.0);
        [(x - cx) * z / f, -(y - cy) * z / f, -z]
    }
}

/// Renders the built-in `room` with the reference path tracer at 160×120 (about a second) and
/// writes `left.png`, `right.png` and `box.glb` into `dir`.
pub fn synthetic(dir: &Path) -> Synthetic {
    let scene = reference::builtin("room").expect("built-in room");
    let images = reference::render(
        &scene,
        &RenderOptions {
            width: Some(160),
            height: Some(120),
            samples: SampleBudget::PerPixel(8),
            ..RenderOptions::default()
        },
    )
    .expect("reference render");
    let left = dir.join("left.png");
    let right = dir.join("right.png");
    Image::from_linear_rgb(&images.left)
        .save_png(&left)
        .expect("write left");
    Image::from_linear_rgb(&images.right)
        .save_png(&right)
        .expect("write right");
    let glb = dir.join("box.glb");
    std::fs::write(&glb, box_glb()).expect("write box.glb");
    let (w, h) = (images.left.width(), images.left.height());
    Synthetic {
        left,
        right,
        glb,
        width: w as u32,
        height: h as u32,
        focal_px: images.calibration.focal_px,
        baseline_m: images.calibration.baseline_m,
        depth_centre_m: *images.depth.get(w / 2, h / 2),
        disparity_centre_px: *images.disparity.get(w / 2, h / 2),
        depth: images.depth.clone(),
    }
}

/// A unit cube from (-0.5, 0, -0.5) to (0.5, 1, 0.5) as GLB: positions and indices only (the
/// loader generates normals and warns).
pub fn box_glb() -> Vec<u8> {
    let mut positions = Vec::new();
    for i in 0..8u32 {
        let x = if i & 1 == 0 { -0.5f32 } else { 0.5 };
        let y = if i & 2 == 0 { 0.0f32 } else { 1.0 };
        let z = if i & 4 == 0 { -0.5f32 } else { 0.5 };
        positions.extend_from_slice(&[x, y, z]);
    }
    // Counter-clockwise from outside.
    let indices: [u32; 36] = [
        0, 4, 6, 0, 6, 2, // -x
        1, 3, 7, 1, 7, 5, // +x
        0, 1, 5, 0, 5, 4, // -y
        2, 6, 7, 2, 7, 3, // +y
        0, 2, 3, 0, 3, 1, // -z
        4, 5, 7, 4, 7, 6, // +z
    ];
    let mut bin: Vec<u8> = positions.iter().flat_map(|v| v.to_le_bytes()).collect();
    let pos_len = bin.len();
    bin.extend(indices.iter().flat_map(|v| v.to_le_bytes()));
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}}],"buffers":[{{"byteLength":{}}}],"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{pos_len}}},{{"buffer":0,"byteOffset":{pos_len},"byteLength":{}}}],"accessors":[{{"bufferView":0,"componentType":5126,"count":8,"type":"VEC3","min":[-0.5,0,-0.5],"max":[0.5,1,0.5]}},{{"bufferView":1,"componentType":5125,"count":36,"type":"SCALAR"}}]}}"#,
        bin.len(),
        indices.len() * 4
    );
    let mut json = json.into_bytes();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

/// Runs `program` with `args` (under `PARALLAX_FFI_WRAPPER` when `wrapped`), without cargo's
/// `LD_LIBRARY_PATH` (the program's rpath names the library this run built).
pub fn run<S: AsRef<std::ffi::OsStr>>(program: &Path, args: &[S], wrapped: bool) -> Output {
    let wrapper = if wrapped {
        split_env("PARALLAX_FFI_WRAPPER")
    } else {
        Vec::new()
    };
    let mut cmd = match wrapper.split_first() {
        Some((w, rest)) => {
            let mut c = Command::new(w);
            c.args(rest).arg(program);
            c
        }
        None => Command::new(program),
    };
    cmd.args(args).env_remove("LD_LIBRARY_PATH");
    cmd.output()
        .unwrap_or_else(|e| panic!("cannot run {}: {e}", program.display()))
}

/// The `key=value` lines of a program's output.
pub fn values(stdout: &[u8]) -> std::collections::HashMap<String, String> {
    String::from_utf8_lossy(stdout)
        .lines()
        .filter_map(|l| l.split_once('='))
        .map(|(k, v)| (k.trim().to_string(), v.trim().to_string()))
        .collect()
}

/// Whether `program` can be started (`program --version` runs).
pub fn have(program: &str) -> bool {
    Command::new(program)
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success())
}

/// Compiles `sources` with `compiler` and `flags`, the header folder and `include_dirs` on the
/// include path, linked against the `libparallax` this run built (rpath set), plus
/// `PARALLAX_FFI_CFLAGS`; panics with the compiler's output on failure.
pub fn compile_native(
    compiler: &str,
    flags: &[&str],
    include_dirs: &[PathBuf],
    sources: &[&Path],
    output: &Path,
) {
    let lib_dir = library_dir();
    let mut cmd = Command::new(compiler);
    cmd.args(flags).arg("-I").arg(root().join("include"));
    for dir in include_dirs {
        cmd.arg("-I").arg(dir);
    }
    let result = cmd
        .args(split_env("PARALLAX_FFI_CFLAGS"))
        .args(sources)
        .arg("-o")
        .arg(output)
        .arg(format!("-L{}", lib_dir.display()))
        .arg(format!("-Wl,-rpath,{}", lib_dir.display()))
        .args(["-lparallax", "-lm", "-lpthread", "-ldl"])
        .output()
        .unwrap_or_else(|e| panic!("cannot run compiler {compiler:?}: {e}"));
    assert!(
        result.status.success(),
        "compiling {sources:?} failed:\n{}",
        String::from_utf8_lossy(&result.stderr)
    );
}

impl Synthetic {
    /// The host examples' arguments: `LEFT RIGHT MODEL FOCAL_PX BASELINE_M X Y OUT`.
    pub fn example_args(&self, x: f32, y: f32, out: &Path) -> Vec<std::ffi::OsString> {
        vec![
            self.left.clone().into_os_string(),
            self.right.clone().into_os_string(),
            self.glb.clone().into_os_string(),
            self.focal_px.to_string().into(),
            self.baseline_m.to_string().into(),
            x.to_string().into(),
            y.to_string().into(),
            out.as_os_str().to_owned(),
        ]
    }
}
