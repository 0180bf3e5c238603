//! The GPU renderer (feature `gpu`): a headless wgpu context, passes, WGSL shaders and readback.

pub mod context;

pub use context::{GpuContext, GpuOptions};
