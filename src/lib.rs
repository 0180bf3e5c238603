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
//! | [`stereo`] | stereo matching: disparity, confidence and depth from a rectified pair |
//! | [`camera`] | calibration, disparity ↔ depth, pinhole camera, depth-buffer encodings |
//! | [`mesh`] | scene mesh from depth, ray queries (BVH), support surfaces, placement, export |
//! | [`light`] | illumination: shadow mask, light sources, environment, SH9, prefiltering |
//! | [`context`] | what scenes share: size caps, the lazily opened GPU |
//! | [`reference`](mod@reference) | CPU path tracer and synthetic stereo scenes with exact ground truth |
//! | [`scene`] | the demand-driven pipeline with cached products and a [`trace::Trace`] |
//! | [`ffi`] | the C ABI (`include/parallax.h`) |
//! | `render` (feature `gpu`) | the headless wgpu context and renderer |

#![warn(missing_docs)]

#[cfg(feature = "gltf")]
pub mod artefact;
pub mod camera;
pub mod context;
pub mod error;
pub mod ffi;
pub mod image;
pub mod light;
pub mod mesh;
pub mod reference;
#[cfg(feature = "gpu")]
pub mod render;
mod robust;
pub mod scene;
pub mod stereo;
pub mod trace;

pub use error::{Error, Result, Status};
/// The vector and matrix crate of the API (pixels, transforms), re-exported so that hosts use the
/// same version.
pub use glam;

/// The README's Rust code blocks, compiled (and, unless marked `no_run`, run) as doctests so that
/// they cannot go stale. Its other blocks are `sh` and `c` (the C one is compiled by
/// `tests/c_example.rs`); a block without a language would be taken for Rust.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;

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
    if cfg!(feature = "unity") {
        f.push("unity");
    }
    if cfg!(feature = "test-hooks") {
        f.push("test-hooks");
    }
    f
}
