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

pub mod context;
mod geometry;
mod gpu_types;
mod options;
mod pipelines;
mod renderer;
mod resources;
mod shadow_views;
#[cfg(test)]
mod tests;

pub use context::{read_texture, GpuContext, GpuOptions};
pub use options::{
    Composite, RenderInputs, RenderOptions, RenderRecord, ShadingMode, ShadowMode,
    SpecularEnvironment, EVSM_EXPONENT_LIMIT,
};
pub use renderer::{Renderer, SHADOW_MEMORY_BUDGET};
