//! Builds every C program in `ffi-tests/` against `include/parallax.h` and the freshly built
//! `libparallax`, and runs it (exit 0 = pass).
//!
//! `.ci/run` runs this test again with:
//! - `PARALLAX_FFI_WRAPPER="valgrind --error-exitcode=1 --leak-check=full --errors-for-leak-kinds=definite"`
//! - `PARALLAX_FFI_CFLAGS="-fsanitize=address,undefined -fno-omit-frame-pointer"`
//!
//! `CC` picks the compiler (default `cc`). The programs get `PARALLAX_DATA`: the shared test data
//! folder as an absolute path, when it exists.

use std::path::{Path, PathBuf};
use std::process::Command;

/// `target/<profile>/deps`, where `cargo test` puts the `libparallax.so` it built with this test
/// run's features (the copy one level up is only refreshed by `cargo build`).
fn library_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    exe.parent()
        .expect("test executable lives in target/<profile>/deps")
        .to_path_buf()
}

fn split_env(name: &str) -> Vec<String> {
    std::env::var(name)
        .map(|v| v.split_whitespace().map(str::to_string).collect())
        .unwrap_or_default()
}

fn compile(source: &Path, output: &Path, lib_dir: &Path) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let mut cmd = Command::new(&cc);
    cmd.args(["-std=c11", "-Wall", "-Wextra", "-Werror", "-pedantic", "-g"])
        .arg("-I")
        .arg(root.join("include"))
        .arg("-I")
        .arg(root.join("ffi-tests"))
        .args(split_env("PARALLAX_FFI_CFLAGS"));
    if cfg!(feature = "test-hooks") {
        cmd.arg("-DPLX_TEST_HOOKS");
    }
    if cfg!(feature = "unity") {
        cmd.arg("-DPLX_FEATURE_UNITY");
    }
    cmd.arg(source)
        .arg("-o")
        .arg(output)
        .arg(format!("-L{}", lib_dir.display()))
        .arg(format!("-Wl,-rpath,{}", lib_dir.display()))
        .arg("-lparallax")
        .args(["-lm", "-lpthread", "-ldl"]);
    let result = cmd
        .output()
        .unwrap_or_else(|e| panic!("cannot run C compiler {cc:?}: {e}"));
    assert!(
        result.status.success(),
        "compiling {} failed:\n{}",
        source.display(),
        String::from_utf8_lossy(&result.stderr)
    );
}

/// `PARALLAX_DATA`, else `../shared/data` next to the crate, made absolute; `None` when absent.
fn shared_data_dir() -> Option<PathBuf> {
    std::env::var_os("PARALLAX_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data"))
        .canonicalize()
        .ok()
        .filter(|p| p.is_dir())
}

#[test]
fn c_programs_pass() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let lib_dir = library_dir();
    assert!(
        lib_dir.join("libparallax.so").exists() || lib_dir.join("libparallax.dylib").exists(),
        "libparallax shared library not found in {}",
        lib_dir.display()
    );
    let out_dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("ffi-tests");
    std::fs::create_dir_all(&out_dir).expect("create output dir");
    let mut sources: Vec<PathBuf> = std::fs::read_dir(root.join("ffi-tests"))
        .expect("ffi-tests/ exists")
        .map(|e| e.expect("dir entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "c"))
        .collect();
    sources.sort();
    assert!(!sources.is_empty(), "no C tests found");
    let wrapper = split_env("PARALLAX_FFI_WRAPPER");
    let mut failures = Vec::new();
    for source in &sources {
        let name = source
            .file_stem()
            .expect("file name")
            .to_string_lossy()
            .to_string();
        let exe = out_dir.join(&name);
        compile(source, &exe, &lib_dir);
        let mut cmd = match wrapper.split_first() {
            Some((program, args)) => {
                let mut c = Command::new(program);
                c.args(args).arg(&exe);
                c
            }
            None => Command::new(&exe),
        };
        // Under valgrind or the sanitizers the C tests leave GPU work out: Mesa's software
        // driver, loaded and unloaded by the Vulkan loader, reports errors and leaks of its own
        // there. The plain run renders.
        let checked = !wrapper.is_empty()
            || split_env("PARALLAX_FFI_CFLAGS")
                .iter()
                .any(|f| f.starts_with("-fsanitize"));
        if checked {
            cmd.env("PARALLAX_FFI_NO_GPU", "1");
        } else {
            cmd.env_remove("PARALLAX_FFI_NO_GPU");
        }
        // cargo's LD_LIBRARY_PATH also lists target/<profile>, whose libparallax may be stale; the
        // program's rpath names the one this run built.
        cmd.env_remove("LD_LIBRARY_PATH");
        // The shared test data, as an absolute path; C tests skip their parts that need it when
        // the variable is absent.
        match shared_data_dir() {
            Some(dir) => cmd.env("PARALLAX_DATA", dir),
            None => cmd.env_remove("PARALLAX_DATA"),
        };
        let result = cmd
            .output()
            .unwrap_or_else(|e| panic!("cannot run {name}: {e}"));
        eprintln!(
            "ffi-tests/{name}.c: {}",
            if result.status.success() {
                "ok"
            } else {
                "FAILED"
            }
        );
        if !result.status.success() {
            failures.push(format!(
                "{name}: {}\n{}{}",
                result.status,
                String::from_utf8_lossy(&result.stdout),
                String::from_utf8_lossy(&result.stderr)
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "C tests failed:\n{}",
        failures.join("\n")
    );
}
