//! # Parallax
//!
//! Puts 3D objects (glTF) into stereo photographs so that they sit at the right depth, hide behind
//! what stands in front of them, are lit like the room and cast soft shadows onto it.
//!
//! The pipeline and its conventions are described in `DESIGN.md` of the project; each stage is a
//! module of plain functions and types that can be used alone:
//!
//! | module | stage |
//! |---|---|
//! | `artefact` (feature `gltf`) | glTF 2.0 artefacts: validated loading, materials, instances |
//! | [`image`] | image buffers and views, sRGB↔linear, PNG/JPEG/PFM/EXR/HDR I/O |
//! | [`camera`] | calibration, disparity ↔ depth |
//! | [`scene`] | the demand-driven pipeline with cached products and a [`trace::Trace`] |
//! | [`ffi`] | the C ABI (`include/parallax.h`) |
//! | `render` (feature `gpu`) | the headless wgpu context and renderer |

#![warn(missing_docs)]

#[cfg(feature = "gltf")]
pub mod artefact;
pub mod camera;
pub mod error;

pub mod image;
#[cfg(feature = "gpu")]
pub mod render;
pub mod scene;
pub mod trace;

pub use error::{Error, Result, Status};

/// The crate version (`Cargo.toml`), e.g. `"0.1.0"`.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");

/// Cargo features this build was compiled with.
pub fn features() -> Vec<&'static str> {
    let mut f = Vec::new();
    if cfg!(feature = "gpu") {
        f.push("gpu");
    }
    if cfg!(feature = "gltf") {
        f.push("gltf");
    }
    if cfg!(feature = "cli") {
        f.push("cli");
    }
    if cfg!(feature = "test-hooks") {
        f.push("test-hooks");
    }
    f
}
