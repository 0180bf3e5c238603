//! `parallax`: the command-line tool. Every subcommand uses the public Rust API only.
//!
//! Exit codes: 0 success; 1 the command failed (bad input file, unsupported data, GPU error — the
//! message on stderr names what was wrong); 2 bad usage (unknown flag, missing argument).

mod common;
#[cfg(all(feature = "gpu", feature = "gltf"))]
mod composite;
#[cfg(all(feature = "gpu", feature = "gltf"))]
mod demo;
mod depth;
mod depth_input;
mod eval;
mod info;
#[cfg(feature = "gltf")]
mod inspect;
mod lights;
mod mesh;
mod plot;
mod previews;
mod surfaces;
mod synth;

use clap::{Parser, Subcommand};

/// Parallax: depth, geometry and lighting from stereo photos, and 3D objects rendered into them.
#[derive(Parser)]
#[command(name = "parallax", version, about, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// The whole pipeline on the embedded default: a synthetic room is path traced as a stereo
    /// pair, reconstructed and lit, and two objects are rendered into it.
    #[cfg(all(feature = "gpu", feature = "gltf"))]
    Demo(demo::Args),
    /// Version, compiled features and the GPU adapters found.
    Info(info::Args),
    /// Scene mesh from a stereo pair, a depth map or disparity + calibration, as GLB, PLY or OBJ.
    Mesh(mesh::Args),
    /// Support planes and the gravity "up" from a stereo pair or depth, as JSON and a preview.
    Surfaces(surfaces::Args),
    /// Light sources, main light, ambient, SH9 and environment of a stereo pair, with a preview.
    Lights(lights::Args),
    /// Disparity, depth and confidence of a rectified stereo pair.
    Depth(depth::Args),
    /// A stereo pair with glTF artefacts rendered in: lit like the room, hidden behind its
    /// objects, casting shadows onto it.
    #[cfg(all(feature = "gpu", feature = "gltf"))]
    Composite(composite::Args),
    /// Benchmarks against ground truth and peers (`parallax eval stereo`).
    Eval(eval::Args),
    /// Render a synthetic stereo scene with exact ground truth (Middlebury layout, composites).
    Synth(synth::Args),
    /// Loads a glTF 2.0 artefact (.gltf/.glb) and prints what it holds, or why it is broken.
    #[cfg(feature = "gltf")]
    Inspect(inspect::Args),
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        #[cfg(all(feature = "gpu", feature = "gltf"))]
        Command::Demo(args) => demo::run(args),
        Command::Info(args) => info::run(args),
        Command::Mesh(args) => mesh::run(args),
        Command::Surfaces(args) => surfaces::run(args),
        Command::Lights(args) => lights::run(args),
        Command::Depth(args) => depth::run(args),
        #[cfg(all(feature = "gpu", feature = "gltf"))]
        Command::Composite(args) => composite::run(args),
        Command::Eval(args) => eval::run(args),
        Command::Synth(args) => synth::run(args),
        #[cfg(feature = "gltf")]
        Command::Inspect(args) => inspect::run(args),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("parallax: error: {e:#}");
            std::process::ExitCode::from(1)
        }
    }
}
