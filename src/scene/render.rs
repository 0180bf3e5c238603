//! The composite of a [`Scene`] (issue 8): the photo with its artefacts rendered in, lit by the
//! scene's lights, hidden behind the photo's geometry and casting shadows onto it.
//!
//! What is left out: with no visible artefact the composite is the photo itself, and nothing else
//! is computed (no stereo, mesh, lights or GPU work). Moving an artefact re-renders only: depth,
//! mesh and lights are reused (the trace shows them `reused`).

use super::Scene;
use crate::error::Result;
use crate::image::Raster;
use crate::render::{Composite, RenderInputs, RenderOptions};
use crate::trace::{StageStatus, Trace};

impl Scene {
    /// Renders the composite of the left view with `options`.
    ///
    /// Uses the host's lights / SH9 / environment where given, else the estimates
    /// ([`Scene::lighting_estimate`]); the photo's estimated shadow mask keeps shadows the photo
    /// already has from being darkened twice (only with estimated lights, whose shadows it
    /// describes). Specular image-based light comes from the SH9 and an analytic DFG fit.
    ///
    /// # Errors
    /// `NotAvailable` without a photo (a stereo pair or [`Scene::set_photo`]); `InvalidArgument` for bad options; as
    /// [`Scene::depth`], [`Scene::lights`] and the renderer (`Gpu` without an adapter: the scene
    /// stays usable).
    pub fn render(&mut self, options: &RenderOptions) -> Result<Composite> {
        options.validate()?;
        self.traced(|scene, trace| scene.render_traced(options, trace))
    }

    fn render_traced(&mut self, options: &RenderOptions, trace: &mut Trace) -> Result<Composite> {
        let pair = self.loaded_pair_traced(trace)?;
        if !self.artefacts().iter().any(|(_, i)| i.visible) {
            trace.record(
                "render",
                StageStatus::Skipped,
                0.0,
                "no visible artefact: the composite is the photo",
            );
            return Ok(photo_only(&pair.left_rgb));
        }
        let base = self.depth_and_intrinsics(trace)?;
        let camera = self.camera_traced(&base, trace)?;
        let mesh = self.mesh_traced(&base, trace)?;
        let host_lights = self.lighting.host_lights.value.clone();
        let (lights, photo_shadow) = match host_lights {
            Some(lights) => {
                trace.record("lighting", StageStatus::Skipped, 0.0, "host lights given");
                (lights, None)
            }
            None => {
                let estimate = self.lighting_estimate_traced(trace)?;
                (estimate.fit.lights.clone(), Some(estimate))
            }
        };
        let sh9 = match self.lighting.host_sh9.value {
            Some(sh) => sh,
            None => self.environment_traced(trace)?.sh9,
        };
        let start = std::time::Instant::now();
        let (renderer, compiled) = self.context.renderer()?;
        if compiled {
            trace.record(
                "renderer",
                StageStatus::Computed,
                start.elapsed().as_secs_f64() * 1e3,
                "first render of this context: GPU opened, shaders and pipelines compiled",
            );
        } else {
            trace.record(
                "renderer",
                StageStatus::Reused,
                0.0,
                "pipelines of the context's earlier renders",
            );
        }
        let inputs = RenderInputs {
            photo: &pair.left_rgb,
            camera: &camera,
            scene_mesh: Some(&mesh),
            artefacts: self.artefacts(),
            lights: &lights,
            sh9: &sh9,
            specular: None,
            photo_shadow: photo_shadow.as_ref().map(|e| &e.shadow_mask),
        };
        let composite = trace.time("render", "artefacts to draw", |_| {
            renderer.render(&inputs, options)
        })?;
        for record in &composite.records {
            let status = if record.computed {
                StageStatus::Computed
            } else {
                StageStatus::Skipped
            };
            trace.record(
                format!("render.{}", record.stage),
                status,
                record.ms,
                record.why.clone(),
            );
        }
        Ok(composite)
    }
}

/// The composite of a scene without artefacts: the photo, ratio 1, nothing covered.
fn photo_only(photo: &Raster<[f32; 3]>) -> Composite {
    let (w, h) = (photo.width(), photo.height());
    Composite {
        composite: photo.clone(),
        mask: Raster::filled(w, h, 0.0),
        shadow_ratio: Raster::filled(w, h, [1.0; 3]),
        artefact_depth: Raster::filled(w, h, 0.0),
        artefact_layer: Raster::filled(w, h, [0.0; 4]),
        records: Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use glam::{Mat4, Vec3};

    use crate::artefact::builtin_glb;
    use crate::camera::StereoCalibration;
    use crate::context::{Context, ContextOptions};
    use crate::light::{Light, Sh9};
    use crate::render::RenderOptions;
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

    #[test]
    fn a_box_before_a_textured_wall_is_drawn_and_shadows_it_and_moving_it_only_rerenders() {
        let mut s = Scene::new(Arc::new(Context::new(ContextOptions::default()).unwrap()));
        // A fronto-parallel wall at Z = f·B/d = 60 · 0.1 / 6 = 1 m.
        let (l, r) = shifted_pair(96, 48, 6);
        s.set_stereo_pair(&l.view(), &r.view()).unwrap();
        s.set_stereo_options(StereoOptions {
            max_disparity: 16,
            ..Scene::default_stereo_options()
        })
        .unwrap();
        s.set_calibration(StereoCalibration::from_focal_baseline(60.0, 0.1, 96, 48).unwrap())
            .unwrap();

        // No artefact: the photo itself, and nothing else computed.
        let photo = s.render(&RenderOptions::default()).unwrap();
        assert_eq!(status(&s, "render"), Some(StageStatus::Skipped));
        assert_eq!(status(&s, "stereo"), None);
        assert!(photo.mask.pixels().iter().all(|m| *m == 0.0));
        assert_eq!(&photo.composite, &s.loaded_pair().unwrap().left_rgb);

        // A 0.2 m box 0.6 m in front of the camera, lit from behind the camera's left shoulder.
        let light = Light::directional(
            Vec3::new(0.4, -0.3, -1.0).normalize().to_array(),
            0.5,
            [3.0; 3],
        );
        s.set_lights(vec![light]).unwrap();
        let mut sh = Sh9::default();
        sh.coefficients[0] = [0.2; 3];
        s.set_sh9(sh).unwrap();
        let glb = builtin_glb("box").unwrap();
        let id = s
            .add_artefact_bytes(&glb, Mat4::from_translation(Vec3::new(0.0, -0.1, -0.6)))
            .unwrap();
        let c = s.render(&RenderOptions::default()).unwrap();
        assert_eq!(status(&s, "render"), Some(StageStatus::Computed));
        assert!(c.composite.pixels().iter().flatten().all(|v| v.is_finite()));
        // The box covers the centre; its shadow falls on the wall down and to the right of it
        // (0.4 m behind it: offset (0.16, −0.12) m, i.e. about (+10, +7) px), outside the box.
        assert!(*c.mask.get(48, 24) > 0.99);
        assert_eq!(*c.mask.get(61, 30), 0.0);
        assert!(
            c.shadow_ratio.get(61, 30)[0] < 0.9,
            "{:?}",
            c.shadow_ratio.get(61, 30)
        );
        assert!(
            c.shadow_ratio.get(5, 5)[0] > 0.98,
            "{:?}",
            c.shadow_ratio.get(5, 5)
        );

        // Moving the box re-renders without re-matching or re-meshing.
        s.set_artefact_transform(id, Mat4::from_translation(Vec3::new(0.1, -0.1, -0.6)))
            .unwrap();
        s.render(&RenderOptions::default()).unwrap();
        assert_eq!(status(&s, "stereo"), Some(StageStatus::Reused));
        assert_eq!(status(&s, "mesh"), Some(StageStatus::Reused));
        assert_eq!(status(&s, "render"), Some(StageStatus::Computed));
    }
}
