//! `include/parallax.h` must equal what cbindgen generates from the sources now, so a changed
//! `extern "C"` signature cannot ship with a stale header.
//!
//! Regenerate with: `PARALLAX_BLESS_HEADER=1 cargo test --test header`

use std::path::{Path, PathBuf};

/// cbindgen follows `mod` declarations from `src/ffi/mod.rs`, so these two roots cover the ABI.
fn ffi_sources(root: &Path) -> Vec<PathBuf> {
    vec![root.join("src/error.rs"), root.join("src/ffi/mod.rs")]
}

fn generate() -> String {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut config =
        cbindgen::Config::from_file(root.join("cbindgen.toml")).expect("cbindgen.toml parses");
    config.after_includes = Some(format!(
        "\n/* Version of the library this header was generated from (Cargo.toml). */\n\
         #define PLX_VERSION_MAJOR {}\n#define PLX_VERSION_MINOR {}\n#define PLX_VERSION_PATCH {}\n\
         #define PLX_VERSION_STRING \"{}\"\n",
        env!("CARGO_PKG_VERSION_MAJOR"),
        env!("CARGO_PKG_VERSION_MINOR"),
        env!("CARGO_PKG_VERSION_PATCH"),
        env!("CARGO_PKG_VERSION"),
    ));
    let mut builder = cbindgen::Builder::new().with_config(config);
    for file in ffi_sources(root) {
        builder = builder.with_src(file);
    }
    let mut out = Vec::new();
    builder
        .generate()
        .expect("cbindgen generates the header")
        .write(&mut out);
    String::from_utf8(out).expect("header is UTF-8")
}

#[test]
fn checked_in_header_matches_the_sources() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("include/parallax.h");
    let fresh = generate();
    if std::env::var_os("PARALLAX_BLESS_HEADER").is_some() {
        std::fs::write(&path, &fresh).expect("write include/parallax.h");
        return;
    }
    let checked_in = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        checked_in == fresh,
        "include/parallax.h is out of date with src/ffi: regenerate it with\n    \
         PARALLAX_BLESS_HEADER=1 cargo test --test header\nand commit the result."
    );
}

#[test]
fn header_version_macros_match_cargo_toml() {
    let header = generate();
    let expect = format!(
        "#define PLX_VERSION_STRING \"{}\"",
        env!("CARGO_PKG_VERSION")
    );
    assert!(header.contains(&expect), "missing {expect}");
    let manifest =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("Cargo.toml")).unwrap();
    let version_line = manifest
        .lines()
        .find(|l| l.starts_with("version = "))
        .expect("Cargo.toml has a version");
    assert!(version_line.contains(env!("CARGO_PKG_VERSION")));
}

/// The functions the header declares (outside comments).
fn declared_functions(header: &str) -> Vec<String> {
    let mut names: Vec<String> = header
        .lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .flat_map(|l| {
            // Every identifier right before a '(' is a declared (or called) function.
            let pieces: Vec<&str> = l.split('(').collect();
            pieces[..pieces.len() - 1]
                .iter()
                .filter_map(|p| {
                    p.rsplit(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                        .next()
                })
                .filter(|w| {
                    w.starts_with("plx_")
                        || w.starts_with("UnityPlugin")
                        || *w == "GetRenderEventFunc"
                })
                .map(str::to_string)
                .collect::<Vec<_>>()
        })
        .collect();
    names.sort();
    names.dedup();
    names
}

#[test]
fn every_declared_function_is_called_by_a_c_test() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let header = std::fs::read_to_string(root.join("include/parallax.h")).unwrap();
    let functions = declared_functions(&header);
    assert!(functions.len() > 50, "{functions:?}");
    let mut c_tests = String::new();
    for entry in std::fs::read_dir(root.join("ffi-tests")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "c") {
            c_tests.push_str(&std::fs::read_to_string(&path).unwrap());
        }
    }
    let untested: Vec<&String> = functions
        .iter()
        .filter(|f| !c_tests.contains(&format!("{f}(")))
        .collect();
    assert!(
        untested.is_empty(),
        "exported but called by no ffi-tests/*.c: {untested:?}"
    );
}
