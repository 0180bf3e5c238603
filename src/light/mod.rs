//! Illumination (thesis §3.3.1, §3.3.4, Appendix B.2): what lights the photographed scene.
//!
//! | file | job |
//! |---|---|
//! | [`model`] | the shared lighting types: [`Light`], [`Sh9`], [`CubeMap`] and the cube-face convention |

pub mod model;

pub use model::{
    cube_direction, cube_texel, sh9_basis_polynomials, CubeLevel, CubeMap, Light, LightKind, Sh9,
    CUBE_FACES,
};
