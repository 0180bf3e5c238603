//! The C11 host example (`examples/c/main.c`, only `parallax.h`): compiled with
//! `cc -std=c11 -Wall -Wextra -Werror -pedantic`, run on the synthetic scene, and its composite
//! checked pixel by pixel against the photo; and the README's C example, compiled and run. `CC`
//! picks the compiler, `PARALLAX_FFI_CFLAGS` adds compiler flags. Not run under
//! `PARALLAX_FFI_WRAPPER` (valgrind): the examples render, and the GPU driver they load (Mesa's
//! llvmpipe, through dlopen) reports errors of its own there; `tests/cpp.rs` covers the wrapper
//! under valgrind without rendering, `ffi-tests/` the C API.

mod composite_common;
mod hosts_common;

use std::path::Path;

use hosts_common::{compile_native, root, run, synthetic, values};

fn compile_c(source: &Path, output: &Path) {
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let flags = ["-std=c11", "-Wall", "-Wextra", "-Werror", "-pedantic", "-g"];
    compile_native(&cc, &flags, &[], &[source], output);
}

#[test]
fn c_example_renders_the_model_into_the_photo_where_it_was_placed() {
    let dir = tempfile::tempdir().expect("temp dir");
    let truth = synthetic(dir.path());
    let (px, py) = (truth.width as f32 * 0.5, truth.height as f32 * 0.75);
    let exe = dir.path().join("parallax_example_c");
    compile_c(&root().join("examples/c/main.c"), &exe);
    let composite = dir.path().join("composite.ppm");
    let out = run(&exe, &truth.example_args(px, py, &composite), false);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "example failed ({}):\n{stdout}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    let v = values(&out.stdout);
    assert_eq!(v["size"], format!("{}x{}", truth.width, truth.height));
    assert_eq!(v["composite"], composite.display().to_string());
    composite_common::check_composite(&truth.left, &composite, px, py, &v);
}

/// The first ```c block of the README's "Use from C/C++" section.
fn readme_c_example() -> String {
    let readme = std::fs::read_to_string(root().join("README.md")).expect("README.md");
    let section = readme
        .split("\n## Use from C/C++\n")
        .nth(1)
        .expect("README has a \"## Use from C/C++\" section");
    let section = section.split("\n## ").next().unwrap_or(section);
    let block = section
        .split("\n```c\n")
        .nth(1)
        .expect("the section has a ```c block");
    block
        .split("\n```")
        .next()
        .expect("the block ends")
        .to_string()
}

#[test]
fn readme_c_example_compiles_and_renders() {
    let dir = tempfile::tempdir().expect("temp dir");
    let source = dir.path().join("readme.c");
    std::fs::write(&source, readme_c_example()).unwrap();
    let exe = dir.path().join("readme_example");
    compile_c(&source, &exe);
    let truth = synthetic(dir.path());
    let (px, py) = (truth.width as f32 * 0.5, truth.height as f32 * 0.75);
    let out = run(
        &exe,
        &[
            truth.left.as_os_str(),
            truth.right.as_os_str(),
            truth.glb.as_os_str(),
            px.to_string().as_ref(),
            py.to_string().as_ref(),
        ],
        false,
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && stdout.starts_with("ok "),
        "README example failed ({}):\n{stdout}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
}
