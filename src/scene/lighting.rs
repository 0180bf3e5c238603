//! The lighting of a [`Scene`] (issue 6): what the host says about the lights, and (once
//! estimated) the shadow mask, lights and environment products.
//!
//! Every estimate can be replaced by the host: its lights, its ambient SH9 and its environment map
//! are inputs with their own versions, so setting one recomputes only what depends on it and never
//! the reconstruction.

use std::sync::Arc;

use super::{Input, Product, Scene};
use crate::error::{Error, Result};
use crate::image::Raster;
use crate::light::{
    estimate_lighting, normals_from_depth, Environment, EnvironmentOptions, EstimateOptions, Light,
    LightingEstimate, Sh9,
};
use crate::trace::{StageStatus, Trace};

/// The lighting inputs the host may give instead of the estimates.
#[derive(Debug, Default, Clone)]
pub(super) struct SceneLighting {
    pub(super) host_lights: Input<Vec<Light>>,
    pub(super) host_sh9: Input<Sh9>,
    pub(super) host_environment: Input<Raster<[f32; 3]>>,
    /// Where the host will insert its objects: the estimated environment is built around it.
    pub(super) insertion_point: Input<[f32; 3]>,
    /// Shadow mask, sources, fitted lights and the photo's environment, estimated together.
    estimate: Product<LightingEstimate>,
    /// The environment built from the host's map.
    host_environment_built: Product<Environment>,
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

    /// Names where the artefacts will sit (camera frame, metres): the estimated environment, and
    /// so the ambient SH9 and what glossy materials reflect, is the photo re-projected around this
    /// point. Without it the estimate takes the median point of the up-facing surfaces (see
    /// [`estimate_lighting`]), which can be metres from an object placed on a table. Setting it
    /// re-estimates the lighting but not the reconstruction; setting the point it already has
    /// changes nothing.
    ///
    /// # Errors
    /// `InvalidArgument` when a coordinate is not finite; the scene is unchanged.
    pub fn set_insertion_point(&mut self, point: [f32; 3]) -> Result<()> {
        if point.iter().any(|c| !c.is_finite()) {
            return Err(Error::invalid(format!(
                "insertion point must be finite, got {point:?}"
            )));
        }
        // Hosts set it every frame; the same point must not re-estimate the lighting.
        if self.lighting.insertion_point.value != Some(point) {
            self.lighting.insertion_point.value = Some(point);
            self.lighting.insertion_point.version = self.bump();
        }
        Ok(())
    }

    /// Back to the estimated insertion point.
    pub fn clear_insertion_point(&mut self) {
        if self.lighting.insertion_point.value.take().is_some() {
            self.lighting.insertion_point.version = self.bump();
        }
    }

    /// The host's lights, if it set them.
    pub fn host_lights(&self) -> Option<&[Light]> {
        self.lighting.host_lights.value.as_deref()
    }

    /// The lighting estimated from the photo (product `lighting`): shadow mask, light sources in
    /// view, the fitted main light and ambient, and the environment around the insertion point
    /// (see [`estimate_lighting`]). When nothing explains the shading, the fit falls back to one
    /// light above the scene and the trace warns.
    ///
    /// # Errors
    /// `NotAvailable` without a photo ([`Scene::set_stereo_pair`] or [`Scene::set_photo`]) or
    /// depth; as [`Scene::depth`] and [`estimate_lighting`].
    pub fn lighting_estimate(&mut self) -> Result<Arc<LightingEstimate>> {
        self.traced(|scene, trace| scene.lighting_estimate_traced(trace))
    }

    pub(super) fn lighting_estimate_traced(
        &mut self,
        trace: &mut Trace,
    ) -> Result<Arc<LightingEstimate>> {
        let pair = self.loaded_pair_traced(trace)?;
        let base = self.depth_and_intrinsics(trace)?;
        let camera = self.camera_traced(&base, trace)?;
        let surfaces = self.surfaces_traced(&base, trace)?;
        let versions = [
            self.loaded_pair.generation,
            self.depth.generation,
            self.camera.generation,
            self.surfaces.generation,
            self.lighting.insertion_point.version,
        ];
        let depth = Arc::clone(&base.0);
        let insertion_point = self.lighting.insertion_point.value;
        let tolerance = self
            .surface_options
            .value
            .unwrap_or_default()
            .membership_tolerance();
        let estimate =
            self.lighting
                .estimate
                .get_or_compute("lighting", &versions, trace, |_| {
                    // Shading is explained by normals: on the support surfaces take the planes'.
                    let mut normals = normals_from_depth(&depth, &camera, 0.05)?;
                    surfaces.snap_normals(&depth, &camera, &mut normals, tolerance);
                    estimate_lighting(
                        &pair.left_rgb,
                        &depth,
                        Some(&normals),
                        &camera,
                        surfaces.up.to_array(),
                        insertion_point,
                        &EstimateOptions::default(),
                    )
                })?;
        trace.record_parts("lighting", &estimate.timings);
        const FALLBACK: &str =
            "lighting: the photo's shading is not explained by any light; using one light above the scene";
        if estimate.fit.fallback_used {
            trace.warn(FALLBACK);
        }
        Ok(estimate)
    }

    /// The lights the renderer uses: the host's ([`Scene::set_lights`]) when given, else the
    /// estimated ones (in-view sources and the fitted out-of-view lights).
    ///
    /// # Errors
    /// As [`Scene::lighting_estimate`] when estimating.
    pub fn lights(&mut self) -> Result<Vec<Light>> {
        if let Some(lights) = &self.lighting.host_lights.value {
            let lights = lights.clone();
            return self.traced(|_, trace| {
                trace.record("lighting", StageStatus::Skipped, 0.0, "host lights given");
                Ok(lights)
            });
        }
        Ok(self.lighting_estimate()?.fit.lights.clone())
    }

    /// The main light: the host's brightest light when it gave lights (`None` when it gave an
    /// empty list), else the fitted main light.
    ///
    /// # Errors
    /// As [`Scene::lights`].
    pub fn main_light(&mut self) -> Result<Option<Light>> {
        if let Some(lights) = &self.lighting.host_lights.value {
            let brightest = lights.iter().copied().max_by(|a, b| {
                let sum = |l: &Light| l.intensity.iter().sum::<f32>();
                sum(a).total_cmp(&sum(b))
            });
            return Ok(brightest);
        }
        Ok(Some(self.lighting_estimate()?.fit.main))
    }

    /// Where the main light is seen from, camera frame, metres: the host's insertion point when
    /// it set one, else the estimate's (see [`Scene::set_insertion_point`]) when the lights are
    /// estimated, else 2 m in front of the camera (host lights without a point). The direction to
    /// a point or area light depends on it.
    ///
    /// # Errors
    /// As [`Scene::lighting_estimate`] when the lights are estimated.
    pub fn main_light_origin(&mut self) -> Result<[f32; 3]> {
        if let Some(point) = self.lighting.insertion_point.value {
            return Ok(point);
        }
        if self.lighting.host_lights.value.is_some() {
            return Ok([0.0, 0.0, -2.0]);
        }
        Ok(self.lighting_estimate()?.insertion_point)
    }

    /// The environment around the insertion point: built from the host's map when given, else
    /// the estimate's.
    ///
    /// # Errors
    /// As [`Environment::from_equirect`] for a host map, else as [`Scene::lighting_estimate`].
    pub fn environment(&mut self) -> Result<Arc<Environment>> {
        self.traced(|scene, trace| scene.environment_traced(trace))
    }

    pub(super) fn environment_traced(&mut self, trace: &mut Trace) -> Result<Arc<Environment>> {
        if let Some(map) = &self.lighting.host_environment.value {
            let versions = [self.lighting.host_environment.version];
            return self.lighting.host_environment_built.get_or_compute(
                "environment",
                &versions,
                trace,
                |_| Environment::from_equirect(map, &EnvironmentOptions::default()),
            );
        }
        let estimate = self.lighting_estimate_traced(trace)?;
        Ok(Arc::new(estimate.environment.clone()))
    }

    /// The ambient light as SH9: the host's ([`Scene::set_sh9`]), else projected from the
    /// environment ([`Scene::environment`]).
    ///
    /// # Errors
    /// As [`Scene::environment`].
    pub fn sh9(&mut self) -> Result<Sh9> {
        if let Some(sh) = self.lighting.host_sh9.value {
            return Ok(sh);
        }
        Ok(self.environment()?.sh9)
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use crate::context::{Context, ContextOptions};
    use crate::light::{Light, LightKind, Sh9};
    use crate::scene::test_support::shifted_pair;
    use crate::scene::Scene;
    use crate::stereo::StereoOptions;
    use crate::trace::StageStatus;

    fn status(scene: &Scene, name: &str) -> Option<StageStatus> {
        scene
            .last_trace()
            .stages()
            .iter()
            .find(|s| s.name == name)
            .map(|s| s.status)
    }

    fn scene_with_pair() -> Scene {
        let mut s = Scene::new(Arc::new(Context::new(ContextOptions::default()).unwrap()));
        let (l, r) = shifted_pair(96, 48, 6);
        s.set_stereo_pair(&l.view(), &r.view()).unwrap();
        s.set_stereo_options(StereoOptions {
            max_disparity: 16,
            ..Scene::default_stereo_options()
        })
        .unwrap();
        s
    }

    #[test]
    fn the_estimate_is_finite_cached_and_replaced_by_the_host() {
        let mut s = scene_with_pair();
        let estimate = s.lighting_estimate().unwrap();
        assert_eq!(status(&s, "lighting"), Some(StageStatus::Computed));
        // Its parts are in the trace, each as long as the estimate measured it.
        for (name, ms) in &estimate.timings {
            let stage = s.last_trace().stages().iter().find(|st| st.name == *name);
            assert!(
                stage.is_some_and(|st| st.status == StageStatus::Computed && st.ms == *ms),
                "{name}: {stage:?}"
            );
        }
        for part in ["lighting.mask", "lighting.fit", "lighting.environment"] {
            assert!(estimate.timings.iter().any(|(n, _)| n == part), "{part}");
        }
        let main = s.main_light().unwrap().unwrap();
        main.validate().unwrap();
        // Estimated lights are seen from the estimate's insertion point.
        assert_eq!(s.main_light_origin().unwrap(), estimate.insertion_point);
        assert!(s.sh9().unwrap().to_array().iter().all(|v| v.is_finite()));
        assert!(estimate
            .shadow_mask
            .pixels()
            .iter()
            .all(|m| (0.0..=1.0).contains(m)));
        // Asked again: reused, not recomputed.
        let again = s.lighting_estimate().unwrap();
        assert!(Arc::ptr_eq(&estimate, &again));
        assert_eq!(status(&s, "lighting"), Some(StageStatus::Reused));

        // The host's lights replace the estimate without estimating.
        let lamp = Light {
            kind: LightKind::Point,
            position: [0.0, 2.0, -3.0],
            direction: [0.0; 3],
            size: 0.1,
            intensity: [5.0, 4.0, 3.0],
            confidence: 1.0,
        };
        s.set_lights(vec![lamp]).unwrap();
        assert_eq!(s.lights().unwrap(), vec![lamp]);
        assert_eq!(status(&s, "lighting"), Some(StageStatus::Skipped));
        assert_eq!(s.main_light().unwrap(), Some(lamp));
        // A host's lights without a host point: seen from 2 m in front of the camera; with one,
        // from it.
        assert_eq!(s.main_light_origin().unwrap(), [0.0, 0.0, -2.0]);
        s.set_insertion_point([0.5, 0.0, -3.0]).unwrap();
        assert_eq!(s.main_light_origin().unwrap(), [0.5, 0.0, -3.0]);
        s.clear_insertion_point();
        s.set_lights(Vec::new()).unwrap();
        assert_eq!(s.main_light().unwrap(), None);
        let bad = Light {
            intensity: [f32::NAN, 0.0, 0.0],
            ..lamp
        };
        let e = s.set_lights(vec![lamp, bad]).unwrap_err();
        assert!(e.to_string().contains("light 1"), "{e}");
        assert!(s.lights().unwrap().is_empty(), "unchanged on error");
        s.clear_lights();
        assert_eq!(s.lights().unwrap(), estimate.fit.lights);

        // The host's SH9 wins; a map is projected when there is no SH9.
        let mut sh = Sh9::default();
        sh.coefficients[0] = [0.25; 3];
        s.set_sh9(sh).unwrap();
        assert_eq!(s.sh9().unwrap(), sh);
        s.clear_sh9();
        s.set_environment_equirect(crate::image::Raster::filled(32, 16, [2.0; 3]))
            .unwrap();
        let projected = s.sh9().unwrap().coefficients[0];
        assert!(
            projected.iter().all(|c| (c - 2.0).abs() < 0.05),
            "{projected:?}"
        );
        assert!(s
            .set_environment_equirect(crate::image::Raster::filled(16, 16, [1.0; 3]))
            .is_err());
        assert!(s
            .set_environment_equirect(crate::image::Raster::filled(32, 16, [f32::INFINITY; 3]))
            .is_err());
        // None of this touched the reconstruction.
        s.lighting_estimate().unwrap();
        assert_eq!(status(&s, "stereo"), Some(StageStatus::Reused));
    }

    #[test]
    fn a_photo_with_host_depth_is_lit_without_a_stereo_pair() {
        let mut s = Scene::new(Arc::new(Context::new(ContextOptions::default()).unwrap()));
        let (photo, _) = shifted_pair(96, 48, 6);
        s.set_photo(&photo.view()).unwrap();
        let e = s.disparity().unwrap_err();
        assert!(e.to_string().contains("set_photo"), "{e}");
        // A floor 1 m below the camera and a wall at 5 m.
        let camera = crate::camera::Camera::from_focal(60.0, 96, 48).unwrap();
        let depth = crate::image::Raster::from_fn(96, 48, |_, y| {
            let below = y as f32 + 0.5 - 24.0;
            if below > 0.0 {
                (60.0 / below).min(5.0)
            } else {
                5.0
            }
        });
        s.set_depth(depth, None, Some(camera)).unwrap();
        let estimate = s.lighting_estimate().unwrap();
        assert_eq!(status(&s, "stereo"), Some(StageStatus::Skipped));
        assert!(s.sh9().unwrap().to_array().iter().all(|v| v.is_finite()));
        assert!(estimate.fit.main.validate().is_ok());
        assert!(s
            .last_trace()
            .warnings()
            .iter()
            .all(|w| !w.contains("identical")));
        // A photo of another size than the host depth is refused; the scene keeps its photo.
        let (small, _) = shifted_pair(48, 48, 6);
        assert!(s.set_photo(&small.view()).is_err());
        assert_eq!(s.photo_size(), Some((96, 48)));
    }

    #[test]
    fn the_environment_is_built_around_the_hosts_insertion_point() {
        let mut s = scene_with_pair();
        let default = s.lighting_estimate().unwrap();
        let point = [0.1, -0.2, -0.5];
        s.set_insertion_point(point).unwrap();
        let moved = s.lighting_estimate().unwrap();
        assert_eq!(status(&s, "lighting"), Some(StageStatus::Computed));
        assert_eq!(status(&s, "stereo"), Some(StageStatus::Reused));
        assert_eq!(moved.insertion_point, point);
        assert_ne!(moved.insertion_point, default.insertion_point);
        // The same point again (a host setting it every frame) keeps the estimate.
        s.set_insertion_point(point).unwrap();
        assert!(Arc::ptr_eq(&moved, &s.lighting_estimate().unwrap()));
        let e = s.set_insertion_point([0.0, f32::NAN, -1.0]).unwrap_err();
        assert!(e.to_string().contains("insertion point"), "{e}");
        assert!(Arc::ptr_eq(&moved, &s.lighting_estimate().unwrap()));
        // Extreme but legal points (far outside the room, at the camera) give a finite answer.
        for far in [[1e30, -1e30, 1e30], [0.0; 3], [f32::MAX, 0.0, -f32::MAX]] {
            s.set_insertion_point(far).unwrap();
            let e = s.lighting_estimate().unwrap();
            assert!(
                e.environment.sh9.to_array().iter().all(|v| v.is_finite()),
                "{far:?}"
            );
            assert!(e.fit.main.validate().is_ok(), "{far:?}");
        }
        s.clear_insertion_point();
        assert_eq!(
            s.lighting_estimate().unwrap().insertion_point,
            default.insertion_point
        );
    }
}
