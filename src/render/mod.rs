//! The GPU renderer (feature `gpu`): a headless wgpu context, and the real-time renderer that
//! puts artefacts into the photo (thesis §3.3.2–3.3.6).
//!
//! | file | job |
//! |---|---|
//! | [`context`] | adapter and device, texture readback |
//! | `options` | [`RenderInputs`], [`RenderOptions`], [`Composite`] |
//! | `renderer` | [`Renderer`]: the passes below |
//! | `geometry` | artefacts and the scene mesh flattened into world-space draws |
//! | `shadow_views` | per light: orthographic box, perspective frustum or cube, or no map |
//! | [`compare`] | the renderer against the reference path tracer (TRUE depth and lights) |
//! | `pipelines`, `resources` | pipelines, bind groups, material textures, environment |
//! | `*.wgsl` | shaders: `shadow`, `common` (lights, shadow filters), `material`, `forward`, `receiver` |
//!
//! Passes of one render:
//! 1. **Shadow maps**: per light view, one layer with the artefacts and one with the scene mesh,
//!    each holding the linear distance (metres) of the nearest caster. Filters run at lookup
//!    (`textureLoad`, no float filtering needed): the thesis' ESM with its contact-shadow
//!    modification, EVSM, or PCSS (see [`ShadowMode`]). Exponentials are taken of depth
//!    *differences* in the light's normalised range and clamped, so no c overflows f32
//!    (stored `e^{c·d}` would overflow f32 at c·d > 88.7 and f16 at c·d > 11.1).
//! 2. **Artefacts**, 4× MSAA: the scene mesh is drawn into depth first with the same projection
//!    (thesis §3.3.6), so artefacts behind the photo's objects are hidden at sample precision;
//!    then opaque and masked artefacts, then blended ones far to near.
//! 3. **Shadow ratio**: the scene mesh as a white Lambertian receiver, per pixel the shading with
//!    the artefacts (their shadows, and their spheres' ambient occlusion) over the shading
//!    without, light by light; where the photo's shadow mask says the surface is already in
//!    shadow the direct term is weighted by `1 − mask` in both, so it is not darkened twice.
//! 4. **Composite** (CPU): `photo × ratio × (1 − α) + artefact` (premultiplied).
//!
//! Shadow maps, the shadow ratio and the artefact depth are 32-bit float targets, or 16-bit ones
//! on a device that cannot render into 32-bit floats (wgpu's OpenGL backend on some drivers;
//! `pipelines::TargetFormats`). Two more allowances for that backend: the shadow maps' array
//! never has a layer count it would take for a plain 2D texture or a cube map
//! (`renderer::shadow_texture_layers`), and every depth test is `GreaterEqual`, since its
//! remap of depth to [−1, 1] rounds reversed depths far away to the cleared 0.

// The renderer draws artefacts, so it needs the glTF types (feature `gltf`); the context does not.
#[cfg(feature = "gltf")]
pub mod compare;
pub mod context;
#[cfg(feature = "gltf")]
mod geometry;
#[cfg(feature = "gltf")]
mod gpu_types;
#[cfg(feature = "gltf")]
mod options;
#[cfg(feature = "gltf")]
mod pipelines;
#[cfg(feature = "gltf")]
mod renderer;
#[cfg(feature = "gltf")]
mod resources;
#[cfg(feature = "gltf")]
mod shadow_views;
#[cfg(feature = "gltf")]
mod shapes;
#[cfg(all(test, feature = "gltf"))]
mod tests;

pub use context::{read_texture, GpuContext, GpuOptions};
#[cfg(feature = "gltf")]
pub use options::{
    Composite, RenderInputs, RenderOptions, RenderRecord, ShadingMode, ShadowMode,
    SpecularEnvironment, EVSM_EXPONENT_LIMIT,
};
#[cfg(feature = "gltf")]
pub use renderer::{Renderer, SHADOW_MEMORY_BUDGET};
