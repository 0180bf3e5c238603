//! What a render takes in and gives back: inputs, options and the composite.

use crate::artefact::ArtefactSet;
use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::image::Raster;
use crate::light::{CubeMap, Light, Sh9};
use crate::mesh::SceneMesh;

/// How artefacts are shaded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ShadingMode {
    /// glTF 2.0 metallic-roughness (spec Appendix B): Lambert diffuse, GGX distribution,
    /// height-correlated Smith visibility, Schlick Fresnel; SH9 diffuse and split-sum specular.
    #[default]
    Pbr,
    /// The thesis' modified Blinn-Phong (eq. 3.27–3.30) with its energy-conservation factor
    /// `c_s = (α + 8) / 8π` and Fresnel factor `c_f`; ambient from the SH9.
    Thesis,
}

/// How shadow maps are filtered.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ShadowMode {
    /// The thesis' exponential shadow test with its contact-shadow modification (eq. 3.36–3.38),
    /// box-filtered over `(2·filter_radius + 1)²` texels. The map stores linear depth; the
    /// exponential is taken of the (receiver − occluder) difference only, so it cannot overflow.
    #[default]
    ThesisEsm,
    /// Exponential variance shadow maps: two warped moments (positive and negative exponent)
    /// and Chebyshev's bound, moments taken relative to the receiver so no exponent overflows.
    Evsm,
    /// Percentage-closer soft shadows: blocker search, penumbra ∝ light size × (d_receiver −
    /// d_blocker) / d_blocker, then percentage-closer filtering over the penumbra.
    Pcss,
    /// No shadows (every light fully visible).
    Off,
}

/// Options of one render.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderOptions {
    /// Artefact shading.
    pub shading: ShadingMode,
    /// Shadow filtering.
    pub shadows: ShadowMode,
    /// Edge of each shadow map, texels, in [512, 4096] (a smaller map is used where the device's
    /// limits or the shadow memory budget demand it; the trace says so).
    pub shadow_map_size: u32,
    /// Filter radius in texels for `ThesisEsm` and `Evsm` (kernel `(2r + 1)²`), and the most taps
    /// from the centre for `Pcss`; in [0, 8].
    pub filter_radius: u32,
    /// `c` of the thesis' exponential test (eq. 3.36), per unit of the light's normalised depth
    /// range: the shadow behind an occluder fades to `1 − e⁻¹` of full light at `1/c` of the
    /// range. Any finite value ≥ 0 is safe (no overflow).
    pub esm_exponent: f32,
    /// Positive and negative EVSM exponents, per unit of normalised depth. Values above
    /// [`EVSM_EXPONENT_LIMIT`] are clamped there (f32 moments overflow beyond it).
    pub evsm_exponents: [f32; 2],
    /// 4× multisampling of the artefacts (anti-aliased edges, also against the photo's own
    /// geometry); `false` renders one sample per pixel.
    pub msaa: bool,
    /// Approximate the artefacts' occlusion of ambient light on the photo (each artefact as a
    /// sphere of equal volume).
    pub ambient_occlusion: bool,
}

/// The largest useful EVSM exponent with f32 moments: the second moment is `e^{2c·Δ}` with a
/// normalised depth difference |Δ| ≤ 1, and f32 overflows past `e^{88.7}`; 42 keeps a margin for
/// the sum over the kernel (Filament uses the same bound). With f16 moments it would be 5.54.
pub const EVSM_EXPONENT_LIMIT: f32 = 42.0;

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            shading: ShadingMode::Pbr,
            shadows: ShadowMode::ThesisEsm,
            shadow_map_size: 1024,
            filter_radius: 2,
            esm_exponent: 3.0,
            evsm_exponents: [40.0, 5.0],
            msaa: true,
            ambient_occlusion: true,
        }
    }
}

impl RenderOptions {
    /// Checks every option.
    ///
    /// # Errors
    /// `InvalidArgument` naming the option: a shadow map size outside [512, 4096], a filter
    /// radius above 8, a negative or non-finite exponent.
    pub fn validate(&self) -> Result<()> {
        if !(512..=4096).contains(&self.shadow_map_size) {
            return Err(Error::invalid(format!(
                "render: shadow_map_size must be in [512, 4096], got {}",
                self.shadow_map_size
            )));
        }
        if self.filter_radius > 8 {
            return Err(Error::invalid(format!(
                "render: filter_radius must be in [0, 8] texels, got {}",
                self.filter_radius
            )));
        }
        let exps = [
            ("esm_exponent", self.esm_exponent),
            ("evsm_exponents[0]", self.evsm_exponents[0]),
            ("evsm_exponents[1]", self.evsm_exponents[1]),
        ];
        for (name, v) in exps {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::invalid(format!(
                    "render: {name} must be finite and >= 0, got {v}"
                )));
            }
        }
        Ok(())
    }
}

/// A prefiltered environment for split-sum specular lighting (Filament's layout).
#[derive(Debug, Clone, Copy)]
pub struct SpecularEnvironment<'a> {
    /// Cube mip chain: level `k` of `n` is GGX-prefiltered radiance for perceptual roughness
    /// `k / (n − 1)`; faces in [`crate::light::CUBE_FACES`] order, in the camera frame.
    pub prefiltered: &'a CubeMap,
    /// The DFG table, `dfg_size × dfg_size` entries: entry `j · dfg_size + i` is for
    /// `n·v = (i + 0.5) / dfg_size` and perceptual roughness `(j + 0.5) / dfg_size`, holding
    /// `(A, B)` of the split sum, specular = prefiltered · (f0 · A + B).
    pub dfg: &'a [[f32; 2]],
    /// Edge of the DFG table.
    pub dfg_size: u32,
}

/// Everything one render reads.
#[derive(Debug, Clone, Copy)]
pub struct RenderInputs<'a> {
    /// The photo, linear RGB (1.0 = the photo's white); its size is the output size and must be
    /// the camera's.
    pub photo: &'a Raster<[f32; 3]>,
    /// The camera the photo was taken with (camera = world frame).
    pub camera: &'a Camera,
    /// The photo's geometry, metres, camera frame: hides artefacts behind it and receives their
    /// shadows. Without it artefacts are drawn over the photo and cast no shadow onto it.
    pub scene_mesh: Option<&'a SceneMesh>,
    /// The artefacts (only visible instances are drawn).
    pub artefacts: &'a ArtefactSet,
    /// Light sources.
    pub lights: &'a [Light],
    /// Ambient light.
    pub sh9: &'a Sh9,
    /// Prefiltered environment for glossy materials; without it, specular ambient comes from the
    /// SH9 (a rough approximation) and an analytic DFG fit.
    pub specular: Option<SpecularEnvironment<'a>>,
    /// Where the photo is already in shadow, in [0, 1] (1 = no direct light reaches the surface
    /// in the photo), same size as the photo. Direct light there is taken as already missing,
    /// so artefacts' shadows do not darken it again.
    pub photo_shadow: Option<&'a Raster<f32>>,
}

/// One decision or timing of a render, for the trace.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderRecord {
    /// Stage name, e.g. `render.shadow_maps`, `render.light[2].shadow`.
    pub stage: String,
    /// `true` when the stage ran, `false` when it was left out.
    pub computed: bool,
    /// Wall-clock milliseconds (0 when left out).
    pub ms: f64,
    /// Why it ran or was left out.
    pub why: String,
}

/// The result of a render, every raster the photo's size, every value finite.
#[derive(Debug, Clone)]
pub struct Composite {
    /// Photo × shadow ratio with the artefacts over it (premultiplied alpha), linear RGB.
    pub composite: Raster<[f32; 3]>,
    /// Fraction of each pixel covered by artefacts, in [0, 1] (anti-aliased edges).
    pub mask: Raster<f32>,
    /// Per-channel factor the photo was multiplied by (artefacts' shadows and blocked ambient),
    /// in [0, 1]; 1 where artefacts change nothing.
    pub shadow_ratio: Raster<[f32; 3]>,
    /// Depth (metres along the optical axis) of the nearest opaque artefact surface at the pixel
    /// centre, 0 where none is seen.
    pub artefact_depth: Raster<f32>,
    /// The artefacts alone, premultiplied linear RGBA (what was laid over the photo).
    pub artefact_layer: Raster<[f32; 4]>,
    /// Decisions and timings, in order.
    pub records: Vec<RenderRecord>,
}
