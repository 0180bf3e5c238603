//! The lighting of a [`Scene`] (issue 6): what the host says about the lights, and (once
//! estimated) the shadow mask, lights and environment products.
//!
//! Every estimate can be replaced by the host: its lights, its ambient SH9 and its environment map
//! are inputs with their own versions, so setting one recomputes only what depends on it and never
//! the reconstruction.

use super::{Input, Scene};
use crate::error::{Error, Result};
use crate::image::Raster;
use crate::light::{Light, Sh9};

/// The lighting inputs the host may give instead of the estimates.
#[derive(Debug, Default, Clone)]
pub(super) struct SceneLighting {
    pub(super) host_lights: Input<Vec<Light>>,
    pub(super) host_sh9: Input<Sh9>,
    pub(super) host_environment: Input<Raster<[f32; 3]>>,
}

/// The most lights a scene accepts (each may get a shadow map).
pub const MAX_LIGHTS: usize = 64;

impl Scene {
    /// Replaces the estimated lights with the host's (an empty list means "no direct light":
    /// only the ambient term lights the artefacts). Adjusting one light is: read the lights,
    /// change it, set them all.
    ///
    /// # Errors
    /// `InvalidArgument` naming the light and the field ([`Light::validate`]), or more than
    /// [`MAX_LIGHTS`] lights; the scene is unchanged.
    pub fn set_lights(&mut self, lights: Vec<Light>) -> Result<()> {
        if lights.len() > MAX_LIGHTS {
            return Err(Error::invalid(format!(
                "{} lights given, at most {MAX_LIGHTS} are supported",
                lights.len()
            )));
        }
        for (i, light) in lights.iter().enumerate() {
            light.validate().map_err(|e| match e {
                Error::InvalidArgument(m) => Error::invalid(format!("light {i}: {m}")),
                other => other,
            })?;
        }
        self.lighting.host_lights.value = Some(lights);
        self.lighting.host_lights.version = self.bump();
        Ok(())
    }

    /// Back to the estimated lights.
    pub fn clear_lights(&mut self) {
        self.lighting.host_lights.value = None;
        self.lighting.host_lights.version = self.bump();
    }

    /// Replaces the estimated ambient light with the host's SH9 (e.g. ARCore's Environmental HDR
    /// coefficients, in [`Sh9`]'s convention).
    ///
    /// # Errors
    /// `InvalidArgument` when a coefficient is not finite; the scene is unchanged.
    pub fn set_sh9(&mut self, sh9: Sh9) -> Result<()> {
        Sh9::from_array(&sh9.to_array())?;
        self.lighting.host_sh9.value = Some(sh9);
        self.lighting.host_sh9.version = self.bump();
        Ok(())
    }

    /// Back to the estimated ambient light.
    pub fn clear_sh9(&mut self) {
        self.lighting.host_sh9.value = None;
        self.lighting.host_sh9.version = self.bump();
    }

    /// Replaces the estimated environment with the host's equirectangular HDR map (linear RGB
    /// radiance relative to the photo's exposure; the centre column looks along −Z, the top row
    /// is +Y, in the camera frame). The ambient SH9 is then projected from it unless the host also
    /// set one.
    ///
    /// # Errors
    /// `InvalidArgument` for an empty map or one not twice as wide as high (± 1 pixel), or a
    /// value that is NaN, infinite or negative; `TooLarge` over the context's pixel cap. The
    /// scene is unchanged.
    pub fn set_environment_equirect(&mut self, map: Raster<[f32; 3]>) -> Result<()> {
        let (w, h) = (map.width(), map.height());
        if w == 0 || h == 0 || w.abs_diff(2 * h) > 1 {
            return Err(Error::invalid(format!(
                "an equirectangular environment must be twice as wide as high, got {w}×{h}"
            )));
        }
        self.context
            .limits()
            .check("environment map", w as u64, h as u64)?;
        if let Some(i) = map
            .pixels()
            .iter()
            .position(|p| p.iter().any(|c| !c.is_finite() || *c < 0.0))
        {
            return Err(Error::invalid(format!(
                "environment pixel ({}, {}) must be finite and >= 0, got {:?}",
                i % w,
                i / w,
                map.pixels()[i]
            )));
        }
        self.lighting.host_environment.value = Some(map);
        self.lighting.host_environment.version = self.bump();
        Ok(())
    }

    /// Back to the estimated environment.
    pub fn clear_environment(&mut self) {
        self.lighting.host_environment.value = None;
        self.lighting.host_environment.version = self.bump();
    }

    /// The host's lights, if it set them.
    pub fn host_lights(&self) -> Option<&[Light]> {
        self.lighting.host_lights.value.as_deref()
    }
}
