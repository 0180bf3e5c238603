//! The C ABI (`include/parallax.h`, generated from this module by cbindgen).
//!
//! Conventions (DESIGN.md, "The C ABI"; modelled on rustls-ffi):
//! - Prefix `plx_`. Opaque handles are created by `plx_X_new` and freed by `plx_X_free`
//!   (NULL allowed, once).
//! - Every fallible function returns `plx_status` and writes its outputs through out-parameters,
//!   only on success.
//! - Every exported function checks its pointers and catches panics: a panic becomes
//!   `PLX_STATUS_PANIC`, never an abort of the host (the crate must not be built with
//!   `panic = "abort"`).
//! - Error detail: `plx_last_error_message` on the handle (not thread-local, because Unity calls
//!   from its main and render threads) and `plx_status_str`.
//! - Option structs begin with a `size` field so they can grow without breaking old callers.

#![allow(non_camel_case_types)]

pub mod artefact;
mod boundary;
pub mod context;
mod handle;
pub mod image;
pub mod image_io;
pub mod light;
pub mod log;
pub mod mesh;
pub mod progress;
pub mod query;
pub mod render;
pub mod scene;
pub mod status;
pub mod stereo;
#[cfg(feature = "test-hooks")]
pub mod test_hooks;
#[cfg(feature = "unity")]
pub mod unity;

pub use crate::error::Status as plx_status;
