//! Illumination (thesis §3.3.1, §3.3.4, Appendix B.2): what lights the photographed scene.
//!
//! | file | job |
//! |---|---|
//! | [`model`] | the shared lighting types: [`Light`], [`Sh9`], [`CubeMap`] and the cube-face convention |
//! | [`shadow_mask`](mod@shadow_mask) | where the photo already has cast shadows (thesis Algorithm 5 and a chromaticity method) |
//! | [`sources`] | light sources seen in the photo: bright blobs → area discs or sphere (point) lights |
//! | [`environment`] | HDR radiance around the insertion point (photo re-projection, host maps) and its SH9 |
//! | [`estimate`] | every stage in one call, for the Scene and the CLI |
//! | [`fit`] | inverse rendering: the out-of-view lights (one or two) and ambient that explain the shading and shadows |
//! | `relight` | how the fitted lights shade the surfaces around the insertion point (fills unseen directions) |
//! | [`prefilter`] | GGX-prefiltered cube mips, the DFG table, the thesis' roughness approximation |
//! | [`normals`] | per-pixel normals from depth |
//! | `filters` | small image filters the estimators share |

pub mod environment;
pub mod estimate;
mod filters;
pub mod fit;
pub mod model;
pub mod normals;
pub mod prefilter;
mod relight;
pub mod shadow_mask;
pub mod sources;

pub use environment::{
    inverse_tone_map, sh9_from_cube, Environment, EnvironmentOptions, EnvironmentSource,
};
pub use estimate::{estimate_lighting, EstimateOptions, LightingEstimate};
pub use filters::luminance;
pub use fit::{fit_lights, FitInputs, FitOptions, LightFit};
pub use model::{
    cube_direction, cube_texel, sh9_basis_polynomials, CubeLevel, CubeMap, Light, LightKind, Sh9,
    CUBE_FACES,
};
pub use normals::normals_from_depth;
pub use prefilter::{dfg_lut, prefilter_ggx, roughness_approximation, sample_cube};
pub use shadow_mask::{continuity_regions, shadow_mask, ShadowMethod, ShadowOptions, NO_REGION};
pub use sources::{detect_sources, SourceOptions};
