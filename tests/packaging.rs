//! Packaging for C/C++ builds: `scripts/install.sh` installs the libraries this `cargo test` built
//! (`target/<profile>/deps`), the headers, a pkg-config file and a CMake package config into a
//! temporary prefix; `examples/c` and `examples/cpp` are then built against it with plain CMake
//! (`find_package(Parallax)`, `-DCMAKE_PREFIX_PATH`) and with `pkg-config --cflags --libs
//! parallax`, run on the synthetic scene, and their composites checked. The generated files carry
//! Cargo.toml's version.
//!
//! Needs `cmake` and `pkg-config` (`.ci/run` installs them); without them the tests fail and say
//! how to install them.

mod composite_common;
mod hosts_common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use hosts_common::{library_dir, root, run, synthetic, values, Synthetic};

const VERSION: &str = env!("CARGO_PKG_VERSION");

/// Fails the test, with an install hint, when `program` cannot be run.
fn need(program: &str) {
    assert!(
        hosts_common::have(program),
        "`{program}` is needed by the packaging tests and was not found: install it, e.g. \
         `sudo apt-get install -y cmake pkg-config` (Debian/Ubuntu; `bash .ci/run` does it)"
    );
}

fn check(what: &str, out: Output) -> Output {
    assert!(
        out.status.success(),
        "{what} failed ({}):\n{}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn output(cmd: &mut Command) -> Output {
    cmd.output()
        .unwrap_or_else(|e| panic!("cannot run {cmd:?}: {e}"))
}

/// Installs into `prefix` from the libraries of this test run.
fn install(prefix: &Path) {
    let out = output(
        Command::new("bash")
            .arg(root().join("scripts/install.sh"))
            .arg(prefix)
            .arg(library_dir()),
    );
    check("scripts/install.sh", out);
    assert!(prefix.join("include/parallax.h").is_file());
    assert!(prefix.join("include/parallax.hpp").is_file());
    assert!(
        prefix.join("lib/libparallax.so").is_file()
            || prefix.join("lib/libparallax.dylib").is_file()
    );
}

/// Runs an example on the synthetic scene, writing its composite, and checks it.
fn run_example(exe: &Path, truth: &Synthetic, out_dir: &Path) {
    let (px, py) = (truth.width as f32 * 0.5, truth.height as f32 * 0.75);
    let composite = out_dir.join(format!(
        "{}.ppm",
        exe.file_name().unwrap().to_string_lossy()
    ));
    let out = run(exe, &truth.example_args(px, py, &composite), false);
    let out = check(&exe.display().to_string(), out);
    let v = values(&out.stdout);
    assert_eq!(v["size"], format!("{}x{}", truth.width, truth.height));
    composite_common::check_composite(&truth.left, &composite, px, py, &v);
}

fn cmake_build(source: &Path, build: &Path, prefix: &Path, extra: &[&str]) -> Output {
    output(
        Command::new("cmake")
            .arg("-S")
            .arg(source)
            .arg("-B")
            .arg(build)
            .arg(format!("-DCMAKE_PREFIX_PATH={}", prefix.display()))
            .arg("-DCMAKE_BUILD_TYPE=Release")
            .args(extra),
    )
}

#[test]
fn generated_files_carry_the_crate_version() {
    let dir = tempfile::tempdir().unwrap();
    let prefix = dir.path().join("prefix");
    install(&prefix);
    let read = |p: &str| std::fs::read_to_string(prefix.join(p)).unwrap();
    let pc = read("lib/pkgconfig/parallax.pc");
    assert!(pc.contains(&format!("\nVersion: {VERSION}\n")), "{pc}");
    assert!(pc.contains(&format!(
        "prefix={}",
        prefix.canonicalize().unwrap().display()
    )));
    let config = read("lib/cmake/Parallax/ParallaxConfig.cmake");
    assert!(config.contains(&format!("set(Parallax_VERSION \"{VERSION}\")")));
    let version = read("lib/cmake/Parallax/ParallaxConfigVersion.cmake");
    assert!(version.contains(&format!("set(PACKAGE_VERSION \"{VERSION}\")")));
    for generated in [&pc, &config, &version] {
        assert!(
            !generated.contains('@'),
            "unfilled placeholder:\n{generated}"
        );
    }
    // The templates take the version from Cargo.toml, never hold one of their own.
    for template in [
        "parallax.pc.in",
        "ParallaxConfig.cmake.in",
        "ParallaxConfigVersion.cmake.in",
    ] {
        let text = std::fs::read_to_string(root().join("packaging").join(template)).unwrap();
        assert!(text.contains("@VERSION@"), "{template}");
        assert!(!text.contains(VERSION), "{template} hard-codes {VERSION}");
    }
    // The installed header is the checked-in one, with the same version macro.
    let header = read("include/parallax.h");
    assert!(header.contains(&format!("#define PLX_VERSION_STRING \"{VERSION}\"")));

    need("pkg-config");
    let out = check(
        "pkg-config --modversion parallax",
        output(
            Command::new("pkg-config")
                .args(["--modversion", "parallax"])
                .env("PKG_CONFIG_PATH", prefix.join("lib/pkgconfig")),
        ),
    );
    assert_eq!(String::from_utf8_lossy(&out.stdout).trim(), VERSION);

    // find_package with a version: the crate's major.minor is accepted, a newer one refused.
    need("cmake");
    let probe = dir.path().join("probe");
    std::fs::create_dir_all(&probe).unwrap();
    std::fs::write(
        probe.join("CMakeLists.txt"),
        "cmake_minimum_required(VERSION 3.16)\nproject(probe C)\n\
         find_package(Parallax ${WANT} REQUIRED)\n\
         message(STATUS \"found Parallax ${Parallax_VERSION}\")\n",
    )
    .unwrap();
    let major: u32 = env!("CARGO_PKG_VERSION_MAJOR").parse().unwrap();
    let minor: u32 = env!("CARGO_PKG_VERSION_MINOR").parse().unwrap();
    let ok = check(
        "find_package(Parallax major.minor)",
        cmake_build(
            &probe,
            &dir.path().join("probe-ok"),
            &prefix,
            &[&format!("-DWANT={major}.{minor}")],
        ),
    );
    assert!(String::from_utf8_lossy(&ok.stdout).contains(&format!("found Parallax {VERSION}")));
    let newer = cmake_build(
        &probe,
        &dir.path().join("probe-newer"),
        &prefix,
        &[&format!("-DWANT={}.0", major + 1)],
    );
    assert!(
        !newer.status.success(),
        "find_package accepted a newer major version"
    );
}

#[test]
fn cmake_find_package_builds_the_c_and_cpp_examples() {
    need("cmake");
    let dir = tempfile::tempdir().unwrap();
    let prefix = dir.path().join("prefix");
    install(&prefix);
    let truth = synthetic(dir.path());
    for (example, exe) in [("c", "parallax_example_c"), ("cpp", "parallax_example_cpp")] {
        let build = dir.path().join(format!("build-{example}"));
        check(
            &format!("cmake configure examples/{example}"),
            cmake_build(&root().join("examples").join(example), &build, &prefix, &[]),
        );
        check(
            &format!("cmake --build examples/{example}"),
            output(Command::new("cmake").arg("--build").arg(&build)),
        );
        run_example(&build.join(exe), &truth, dir.path());
    }
    // The static library, when this build made one: Parallax::parallax_static.
    if prefix.join("lib/libparallax.a").is_file() {
        let build = dir.path().join("build-c-static");
        check(
            "cmake configure examples/c (static)",
            cmake_build(
                &root().join("examples/c"),
                &build,
                &prefix,
                &["-DPARALLAX_STATIC=ON"],
            ),
        );
        check(
            "cmake --build examples/c (static)",
            output(Command::new("cmake").arg("--build").arg(&build)),
        );
        let exe = build.join("parallax_example_c");
        let static_exe: PathBuf = dir.path().join("parallax_example_c_static");
        std::fs::rename(&exe, &static_exe).unwrap();
        // Linked statically: it does not need libparallax.so.
        let ldd = output(Command::new("ldd").arg(&static_exe));
        assert!(
            !String::from_utf8_lossy(&ldd.stdout).contains("libparallax"),
            "{}",
            String::from_utf8_lossy(&ldd.stdout)
        );
        run_example(&static_exe, &truth, dir.path());
    }
}

#[test]
fn pkg_config_builds_the_c_and_cpp_examples() {
    need("pkg-config");
    let dir = tempfile::tempdir().unwrap();
    let prefix = dir.path().join("prefix");
    install(&prefix);
    let flags = check(
        "pkg-config --cflags --libs parallax",
        output(
            Command::new("pkg-config")
                .args(["--cflags", "--libs", "parallax"])
                .env("PKG_CONFIG_PATH", prefix.join("lib/pkgconfig")),
        ),
    );
    let flags: Vec<String> = String::from_utf8_lossy(&flags.stdout)
        .split_whitespace()
        .map(str::to_string)
        .collect();
    assert!(flags.iter().any(|f| f == "-lparallax"), "{flags:?}");
    let truth = synthetic(dir.path());
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let cxx = std::env::var("CXX").unwrap_or_else(|_| "c++".into());
    for (compiler, std, source, exe) in [
        (&cc, "-std=c11", "examples/c/main.c", "parallax_example_c"),
        (
            &cxx,
            "-std=c++17",
            "examples/cpp/main.cpp",
            "parallax_example_cpp",
        ),
    ] {
        let exe = dir.path().join(exe);
        check(
            &format!("{compiler} {source} $(pkg-config --cflags --libs parallax)"),
            output(
                Command::new(compiler)
                    .args([std, "-Wall", "-Wextra", "-Werror", "-pedantic", "-O1"])
                    .arg(root().join(source))
                    .arg("-o")
                    .arg(&exe)
                    .args(&flags)
                    .arg(format!("-Wl,-rpath,{}", prefix.join("lib").display())),
            ),
        );
        run_example(&exe, &truth, dir.path());
    }
}
