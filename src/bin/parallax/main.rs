//! `parallax`: the command-line tool. Every subcommand uses the public Rust API only.
//!
//! Exit codes: 0 success; 1 the command failed (bad input file, unsupported data, GPU error — the
//! message on stderr names what was wrong); 2 bad usage (unknown flag, missing argument).

mod common;
mod info;
#[cfg(feature = "gltf")]
mod inspect;

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
    /// Version, compiled features and the GPU adapters found.
    Info(info::Args),
    /// Loads a glTF 2.0 artefact (.gltf/.glb) and prints what it holds, or why it is broken.
    #[cfg(feature = "gltf")]
    Inspect(inspect::Args),
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Info(args) => info::run(args),
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
