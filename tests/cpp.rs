//! The C++ wrapper (`bindings/cpp/parallax.hpp`) and the C++ host example (`examples/cpp/`):
//! compiled with `g++ -std=c++17 -Wall -Wextra -Werror`, run on a synthetic scene rendered by the
//! reference path tracer, its printed results checked against the scene's ground truth and its
//! composite (a PPM) against the photo. The wrapper must wrap every function of the header. `.ci/run`
//! runs it again under valgrind (`PARALLAX_FFI_WRAPPER`). `CXX` picks the compiler.

mod composite_common;
mod hosts_common;

use std::path::Path;

use hosts_common::{compile_native, root, run, split_env, synthetic, values};

fn compile_cpp(sources: &[&Path], output: &Path) {
    let cxx = std::env::var("CXX").unwrap_or_else(|_| "g++".into());
    let mut flags = vec![
        "-std=c++17",
        "-Wall",
        "-Wextra",
        "-Werror",
        "-pedantic",
        "-g",
    ];
    if cfg!(feature = "unity") {
        flags.push("-DPLX_FEATURE_UNITY");
    }
    compile_native(
        &cxx,
        &flags,
        &[root().join("bindings/cpp")],
        sources,
        output,
    );
}

fn number(v: &std::collections::HashMap<String, String>, key: &str) -> f64 {
    v.get(key)
        .unwrap_or_else(|| panic!("example printed no {key}: {v:?}"))
        .parse()
        .unwrap_or_else(|e| panic!("{key}: {e}"))
}

#[test]
fn cpp_example_reconstructs_the_synthetic_scene_and_stands_the_model_on_its_floor() {
    let dir = tempfile::tempdir().expect("temp dir");
    let truth = synthetic(dir.path());
    // A floor pixel of the room, below the image centre.
    let (px, py) = (truth.width as f32 * 0.5, truth.height as f32 * 0.75);
    let floor = truth.point_at(px, py);
    let exe = dir.path().join("parallax_example_cpp");
    compile_cpp(&[&root().join("examples/cpp/main.cpp")], &exe);
    let composite = dir.path().join("composite.ppm");
    // Under valgrind (`PARALLAX_FFI_WRAPPER`) the example leaves out the render: the GPU driver
    // it would load (Mesa's llvmpipe, through dlopen) reports errors of its own there.
    let render = split_env("PARALLAX_FFI_WRAPPER").is_empty();
    let mut args: Vec<&std::ffi::OsStr> = vec![
        truth.left.as_os_str(),
        truth.right.as_os_str(),
        truth.glb.as_os_str(),
    ];
    let numbers = [
        truth.focal_px.to_string(),
        truth.baseline_m.to_string(),
        px.to_string(),
        py.to_string(),
    ];
    args.extend(numbers.iter().map(|n| std::ffi::OsStr::new(n.as_str())));
    if render {
        args.push(composite.as_os_str());
    }
    let out = run(&exe, &args, true);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "example failed ({}):\n{stdout}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    let v = values(&out.stdout);
    assert_eq!(v["size"], format!("{}x{}", truth.width, truth.height));
    // The wrapper hands out what the library computes: the same pipeline through the Rust API
    // on the same files gives the same numbers.
    let (rust_d, rust_z) = rust_reference(&truth);
    let d = number(&v, "disparity_centre_px");
    let z = number(&v, "depth_centre_m");
    assert!((d - rust_d).abs() < 1e-3, "C++ {d} px, Rust {rust_d} px");
    assert!(
        (z - rust_z).abs() < 1e-3 * rust_z,
        "C++ {z} m, Rust {rust_z} m"
    );
    // And it is the scene's depth, within the matcher's error on this small, noisy render
    // (docs/reconstruction-eval.md: median depth errors of 8 % at 16 spp, larger here).
    let (d_true, z_true) = (
        truth.disparity_centre_px as f64,
        truth.depth_centre_m as f64,
    );
    assert!(
        (d - d_true).abs() < 1.0,
        "disparity {d} px, truth {d_true} px"
    );
    assert!(
        (z - z_true).abs() < 0.4 * z_true,
        "depth {z} m, truth {z_true} m"
    );
    assert!(number(&v, "mesh_triangles") > 1000.0, "{stdout}");
    // The box stands on the scene point the camera sees at that pixel: on the pixel's true ray,
    // at the picked point, at a distance within the matcher's error (see above), 0.3 m tall (its largest side).
    let vec = |key: &str| -> [f64; 3] {
        let parts: Vec<f64> = v[key].split(',').map(|x| x.parse().unwrap()).collect();
        [parts[0], parts[1], parts[2]]
    };
    let (base, top, hit) = (vec("artefact_base"), vec("artefact_top"), vec("point"));
    assert_eq!(v["hit"], "1");
    let dist = |a: [f64; 3], b: [f64; 3]| {
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    };
    let floor = floor.map(f64::from);
    let (range, true_range) = (dist(base, [0.0; 3]), dist(floor, [0.0; 3]));
    let cos = (0..3).map(|i| base[i] * floor[i]).sum::<f64>() / (range * true_range);
    assert!(
        cos > 0.9998,
        "base {base:?} is off the pixel's ray {floor:?}"
    );
    assert!(dist(base, hit) < 0.01, "base {base:?}, picked {hit:?}");
    assert!(
        (range - true_range).abs() < 0.4 * true_range,
        "base {range} m away, true floor point {true_range} m"
    );
    assert!(
        (dist(top, base) - 0.3).abs() < 1e-3,
        "top {top:?}, base {base:?}"
    );
    // Normals were generated for the positions-only box: one loader warning.
    assert_eq!(number(&v, "artefact_warnings"), 1.0, "{stdout}");
    assert_eq!(v["clone_reused_mesh"], "1");
    assert!(number(&v, "progress_stages") >= 3.0, "{stdout}");
    // The photo's mean green channel is that of the left PNG.
    let left = parallax::image::Image::load(&truth.left, &Default::default()).unwrap();
    let bytes = left.as_bytes();
    let bpp = left.format().bytes_per_pixel();
    let mean: f64 = bytes.chunks_exact(bpp).map(|p| p[1] as f64).sum::<f64>()
        / (truth.width * truth.height) as f64;
    assert!((number(&v, "photo_mean_green") - mean).abs() < 0.01);
    // The composite: the box drawn where it was placed, the photo unchanged far from it.
    if render {
        assert_eq!(v["composite_size"], v["size"]);
        assert!(v["sh9_dc"]
            .split(',')
            .all(|c| c.parse::<f64>().is_ok_and(f64::is_finite)));
        assert!(v.contains_key("lights"), "{stdout}");
        composite_common::check_composite(&truth.left, &composite, px, py, &v);
    }
}

/// Every function `include/parallax.h` declares (but the test hooks and the entry points Unity
/// itself calls) has a wrapper in `bindings/cpp/parallax.hpp`, so the two cannot drift apart.
#[test]
fn cpp_wrapper_covers_every_function_of_the_header() {
    let header = std::fs::read_to_string(root().join("include/parallax.h")).unwrap();
    let wrapper = std::fs::read_to_string(root().join("bindings/cpp/parallax.hpp")).unwrap();
    let mut functions = Vec::new();
    for line in header.lines() {
        // Declarations start in column 0 with their return type; comments, macros, typedefs and
        // struct fields do not.
        let starts_declaration =
            line.starts_with(|c: char| c.is_ascii_alphabetic()) && !line.starts_with("typedef");
        let Some(open) = line.find('(') else { continue };
        if !starts_declaration {
            continue;
        }
        let name = line[..open]
            .rsplit(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
            .next()
            .unwrap_or_default();
        if name.starts_with("plx_") {
            functions.push(name.to_string());
        }
    }
    assert!(functions.len() > 40, "found only {functions:?}");
    let missing: Vec<&String> = functions
        .iter()
        .filter(|f| f.as_str() != "plx_test_panic")
        .filter(|f| {
            // Called, or passed as a function pointer.
            !wrapper
                .match_indices(f.as_str())
                .any(|(i, _)| wrapper[i + f.len()..].starts_with(['(', ')']))
        })
        .collect();
    assert!(
        missing.is_empty(),
        "bindings/cpp/parallax.hpp wraps none of {missing:?}"
    );
}

/// Disparity and depth at the centre pixel through the Rust API, as the example computes them.
fn rust_reference(truth: &hosts_common::Synthetic) -> (f64, f64) {
    use parallax::camera::StereoCalibration;
    use parallax::context::Context;
    use parallax::image::Image;
    use parallax::scene::Scene;
    let limits = Default::default();
    let left = Image::load(&truth.left, &limits).unwrap();
    let right = Image::load(&truth.right, &limits).unwrap();
    let mut scene = Scene::new(std::sync::Arc::new(
        Context::new(Default::default()).unwrap(),
    ));
    scene.set_stereo_pair(&left.view(), &right.view()).unwrap();
    let (w, h) = (truth.width as usize, truth.height as usize);
    let d = *scene.disparity().unwrap().disparity.get(w / 2, h / 2) as f64;
    scene
        .set_calibration(StereoCalibration {
            focal_px: truth.focal_px,
            cx: w as f64 / 2.0,
            cy: h as f64 / 2.0,
            baseline_m: truth.baseline_m,
            doffs: 0.0,
            max_disparity: None,
        })
        .unwrap();
    let z = *scene.depth().unwrap().get(w / 2, h / 2) as f64;
    (d, z)
}

/// `tests/cpp/wrapper.cpp`: the wrapper's lighting, image, composite and Unity functions, and its
/// exceptions, on an in-memory scene without artefacts (no GPU, so it runs under valgrind).
#[test]
fn cpp_wrapper_functions_behave_like_the_c_api() {
    let dir = tempfile::tempdir().expect("temp dir");
    let exe = dir.path().join("wrapper");
    compile_cpp(&[&root().join("tests/cpp/wrapper.cpp")], &exe);
    let out = run::<&str>(&exe, &[], true);
    assert!(
        out.status.success(),
        "tests/cpp/wrapper.cpp failed ({}):\n{}{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}
