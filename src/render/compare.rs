//! The renderer against the reference path tracer on a built-in scene, with TRUE depth and TRUE
//! lights: separates the renderer's own error from the estimation stages'. `parallax eval
//! composite` renders the truth once ([`render_truth`]), measures the renderer with the true
//! inputs ([`compare_true_inputs`]) and the whole pipeline on the same photo
//! ([`ReferenceTruth::errors`]).

use std::sync::Arc;
use std::time::Instant;

use glam::{Mat4, Vec3, Vec4};

use super::options::{Composite, RenderInputs, RenderOptions};
use super::renderer::Renderer;
use super::shapes::{cube, sphere};
use crate::artefact::{Artefact, ArtefactSet, Material};
use crate::camera::{Camera, StereoCalibration};
use crate::error::{Error, Result};
use crate::image::Raster;
use crate::light::{sh9_from_cube, CubeLevel, Light, LightKind, Sh9};
use crate::mesh::{MeshOptions, SceneMesh};
use crate::reference::{self, LightRecord, Object, SampleBudget, Shape};

/// What to compare.
#[derive(Debug, Clone)]
pub struct ComparisonSetup {
    /// A built-in reference scene (`room`, `two-lights`, `clutter`, `window`).
    pub scene: String,
    /// Inserted shapes: (`sphere` | `box` | …, world position of the lowest point, scale).
    pub inserts: Vec<(String, [f32; 3], f32)>,
    /// Image width (height keeps the rig's aspect).
    pub width: u32,
    /// Path-tracer samples per pixel.
    pub samples_per_pixel: u32,
    /// Renderer configurations to measure.
    pub configs: Vec<RenderOptions>,
}

impl ComparisonSetup {
    /// The room with a glossy sphere on the table and a box on the floor half behind the table.
    pub fn room(width: u32, samples_per_pixel: u32, configs: Vec<RenderOptions>) -> Self {
        ComparisonSetup {
            scene: "room".into(),
            inserts: vec![
                ("sphere".into(), [0.0, 0.75, -1.6], 1.0),
                ("box".into(), [0.7, 0.0, -2.3], 1.0),
            ],
            width,
            samples_per_pixel,
            configs,
        }
    }

    /// A built-in scene with two inserted shapes: a glossy sphere on the front of its table and
    /// a diffuse box on the floor behind the table's right edge (partly hidden by it), placed
    /// clear of the scene's own objects.
    ///
    /// # Errors
    /// `InvalidArgument` for a name that is not a built-in scene.
    pub fn for_scene(
        name: &str,
        width: u32,
        samples_per_pixel: u32,
        configs: Vec<RenderOptions>,
    ) -> Result<Self> {
        // `room` and `two-lights` have their table at x = 0, `clutter` and `window` at x = 0.2.
        let (sphere_x, box_x) = match name {
            "room" | "two-lights" => (0.0, 0.7),
            "clutter" | "window" => (0.25, 0.95),
            other => {
                return Err(Error::invalid(format!(
                    "no comparison set up for scene {other:?}; built-in scenes: {}",
                    reference::BUILTIN_SCENES.join(", ")
                )))
            }
        };
        Ok(ComparisonSetup {
            scene: name.into(),
            inserts: vec![
                ("sphere".into(), [sphere_x, 0.75, -1.55], 1.0),
                ("box".into(), [box_x, 0.0, -2.3], 1.0),
            ],
            width,
            samples_per_pixel,
            configs,
        })
    }
}

/// Mean absolute error (linear light, over channels) and PSNR (peak 1) of one region.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct RegionError {
    /// Pixels in the region.
    pub pixels: usize,
    /// Mean absolute error.
    pub mae: f64,
    /// PSNR in dB (infinite for an exact match; NaN for an empty region).
    pub psnr: f64,
}

/// The error of one composite against the ground truth, per region.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct RegionErrors {
    /// Whole image.
    pub image: RegionError,
    /// Where the reference shows the inserted objects (coverage > 0.5).
    pub artefact: RegionError,
    /// Outside the objects where the reference's ratio drops below 0.95 (their shadows).
    pub shadow: RegionError,
    /// Artefact and shadow regions together: every pixel the insertion should change.
    pub affected: RegionError,
}

/// One measured configuration.
#[derive(Debug, Clone)]
pub struct ComparisonRow {
    /// The options rendered with.
    pub options: RenderOptions,
    /// Whole image.
    pub image: RegionError,
    /// Where the reference shows the inserted objects (coverage > 0.5).
    pub artefact: RegionError,
    /// Outside the objects where the reference's ratio drops below 0.95 (their shadows).
    pub shadow: RegionError,
    /// Artefact and shadow regions together.
    pub affected: RegionError,
    /// Wall-clock time of the render call, milliseconds.
    pub render_ms: f64,
}

/// The reference's side of a comparison.
#[derive(Debug, Clone)]
pub struct ComparisonResult {
    /// Per configuration.
    pub rows: Vec<ComparisonRow>,
    /// Path tracer's time for the composite (with and without the objects), seconds.
    pub reference_seconds: f64,
    /// Samples per pixel of the reference.
    pub samples_per_pixel: u32,
    /// Image size.
    pub size: (u32, u32),
}

/// What the path tracer rendered for one comparison: the ground-truth composite, and the true
/// inputs (photo, depth, lights, environment) that a renderer may be given instead of estimates.
#[derive(Debug, Clone)]
pub struct ReferenceTruth {
    /// The left view without the inserted objects (the "photo"), linear RGB, unclipped.
    pub photo: Raster<[f32; 3]>,
    /// The right view without the objects, linear RGB, when asked for (stereo input); else
    /// `None`.
    pub right: Option<Raster<[f32; 3]>>,
    /// The rig (focal length, principal point, baseline).
    pub calibration: StereoCalibration,
    /// True depth of the left view, metres (NaN where no surface).
    pub depth: Raster<f32>,
    /// True lights, left camera frame.
    pub lights: Vec<Light>,
    /// SH9 of the true ambient at the first inserted object: path-traced radiance arriving 10 cm
    /// above its base from everything but the emitters (the renderer adds those as lights).
    pub sh9: Sh9,
    /// The ground-truth composite, linear RGB.
    pub composite: Raster<[f32; 3]>,
    /// Coverage of the inserted objects in the ground truth.
    pub mask: Raster<f32>,
    /// Ground-truth ratio composite / photo.
    pub ratio: Raster<[f32; 3]>,
    /// The inserted objects as renderer artefacts with their left-camera-frame transforms.
    pub artefacts: Vec<(Arc<Artefact>, Mat4)>,
    /// Path tracer's time for the composite (with and without the objects), seconds.
    pub reference_seconds: f64,
    /// Samples per pixel of the composite.
    pub samples_per_pixel: u32,
}

impl ReferenceTruth {
    /// Image size (width, height).
    pub fn size(&self) -> (u32, u32) {
        (
            self.composite.width() as u32,
            self.composite.height() as u32,
        )
    }

    /// The error of `ours` against the ground truth per region. `ldr` compares both clipped to
    /// [0, 1]: what a composite made from an 8-bit photo can at best reproduce, and what a host
    /// shows of ours (an RGBA8 composite, or any display) — a highlight above the photo's white
    /// is white in both, however far above it the renderer put it.
    pub fn errors(&self, ours: &Raster<[f32; 3]>, ldr: bool) -> RegionErrors {
        let clip = |r: &Raster<[f32; 3]>| r.map(|c| c.map(|v| v.clamp(0.0, 1.0)));
        let (clipped_truth, clipped_ours);
        let (truth, ours) = if ldr {
            clipped_truth = clip(&self.composite);
            clipped_ours = clip(ours);
            (&clipped_truth, &clipped_ours)
        } else {
            (&self.composite, ours)
        };
        let in_artefact = |x: usize, y: usize| *self.mask.get(x, y) > 0.5;
        let in_shadow = |x: usize, y: usize| {
            *self.mask.get(x, y) < 0.01 && self.ratio.get(x, y).iter().sum::<f32>() / 3.0 < 0.95
        };
        RegionErrors {
            image: region_error(ours, truth, |_, _| true),
            artefact: region_error(ours, truth, in_artefact),
            shadow: region_error(ours, truth, in_shadow),
            affected: region_error(ours, truth, |x, y| in_artefact(x, y) || in_shadow(x, y)),
        }
    }

    /// The artefacts as an [`ArtefactSet`].
    ///
    /// # Errors
    /// As [`ArtefactSet::add`].
    pub fn artefact_set(&self) -> Result<ArtefactSet> {
        let mut set = ArtefactSet::new();
        for (a, t) in &self.artefacts {
            set.add(a.clone(), *t)?;
        }
        Ok(set)
    }
}

/// A reference light record as a renderer [`Light`] (camera frame).
///
/// # Errors
/// `Format` for a record missing a field its kind needs.
pub fn light_from_record(r: &LightRecord) -> Result<Light> {
    let missing = |what: &str| Error::format(format!("{} light record has no {what}", r.kind));
    match r.kind.as_str() {
        "directional" => Ok(Light::directional(
            r.direction.ok_or_else(|| missing("direction"))?,
            r.angular_diameter_deg.unwrap_or(0.0),
            r.irradiance.ok_or_else(|| missing("irradiance"))?,
        )),
        "sphere" => Ok(Light {
            kind: LightKind::Point,
            position: r.position.ok_or_else(|| missing("position"))?,
            direction: [0.0, -1.0, 0.0],
            size: 2.0 * r.radius.unwrap_or(0.0),
            intensity: r.intensity.ok_or_else(|| missing("intensity"))?,
            confidence: 1.0,
        }),
        "rect" => {
            let [a, b] = r.size.ok_or_else(|| missing("size"))?;
            Ok(Light {
                kind: LightKind::Area,
                position: r.position.ok_or_else(|| missing("position"))?,
                direction: r.normal.ok_or_else(|| missing("normal"))?,
                // The disc of the same area.
                size: 2.0 * (a * b / std::f32::consts::PI).sqrt(),
                intensity: r.intensity.ok_or_else(|| missing("intensity"))?,
                confidence: 1.0,
            })
        }
        other => Err(Error::format(format!(
            "unknown light record kind {other:?}"
        ))),
    }
}

/// SH9 of an equirectangular radiance map in the camera frame (centre column = −z, top row =
/// +y), by direct projection.
pub fn sh9_from_equirect(env: &Raster<[f32; 3]>) -> Sh9 {
    let (w, h) = (env.width(), env.height());
    let mut proj = [[0.0f32; 3]; 9];
    if w == 0 || h == 0 {
        return Sh9::default();
    }
    let d_area = (2.0 * std::f32::consts::PI / w as f32) * (std::f32::consts::PI / h as f32);
    for j in 0..h {
        let theta = std::f32::consts::PI * (j as f32 + 0.5) / h as f32;
        for i in 0..w {
            let lambda = 2.0 * std::f32::consts::PI * ((i as f32 + 0.5) / w as f32 - 0.5);
            let (x, y, z) = (
                theta.sin() * lambda.sin(),
                theta.cos(),
                -theta.sin() * lambda.cos(),
            );
            let y_lm = [
                0.282_095,
                0.488_603 * y,
                0.488_603 * z,
                0.488_603 * x,
                1.092_548 * x * y,
                1.092_548 * y * z,
                0.315_392 * (3.0 * z * z - 1.0),
                1.092_548 * x * z,
                0.546_274 * (x * x - y * y),
            ];
            let l = env.get(i, j);
            let weight = d_area * theta.sin();
            for (p, yv) in proj.iter_mut().zip(y_lm) {
                for k in 0..3 {
                    p[k] += l[k] * yv * weight;
                }
            }
        }
    }
    Sh9::from_radiance_projection(proj)
}

/// The renderer's artefact for a reference shape (sphere and box; a texture becomes its mean
/// colour).
fn artefact_for(object: &Object, world_to_camera: Mat4) -> Result<(Arc<Artefact>, Mat4)> {
    let m = &object.material;
    let mut base = Vec3::from(m.base_color);
    if let Some(t) = &m.texture {
        base = (base + Vec3::from(t.color)) * 0.5;
    }
    let material = Material {
        base_color_factor: Vec4::new(base.x, base.y, base.z, 1.0),
        metallic_factor: m.metallic,
        roughness_factor: m.roughness,
        ..Material::default()
    };
    let transform = world_to_camera * object.transform.matrix();
    match &object.shape {
        Shape::Sphere { radius, .. } => Ok((
            sphere(material),
            transform * Mat4::from_scale(Vec3::splat(*radius)),
        )),
        Shape::Box { size } => Ok((
            cube(material),
            transform * Mat4::from_scale(Vec3::from(*size)),
        )),
        other => Err(Error::Unsupported(format!(
            "comparison: inserted shape {other:?} has no renderer counterpart here (sphere, box)"
        ))),
    }
}

fn region_error(
    ours: &Raster<[f32; 3]>,
    truth: &Raster<[f32; 3]>,
    inside: impl Fn(usize, usize) -> bool,
) -> RegionError {
    let (mut n, mut abs, mut sq) = (0usize, 0.0f64, 0.0f64);
    for y in 0..truth.height() {
        for x in 0..truth.width() {
            if !inside(x, y) {
                continue;
            }
            n += 1;
            for k in 0..3 {
                let d = (ours.get(x, y)[k] - truth.get(x, y)[k]) as f64;
                abs += d.abs();
                sq += d * d;
            }
        }
    }
    let count = (3 * n) as f64;
    let mse = sq / count;
    RegionError {
        pixels: n,
        mae: abs / count,
        psnr: 10.0 * (1.0 / mse).log10(),
    }
}

/// Renders the setup's scene with the path tracer: the ground-truth composite (with and without
/// the inserted objects, the same random numbers), TRUE depth, lights and environment, and with
/// `stereo_views` the right view at the same sample count (the input of a stereo pipeline).
///
/// # Errors
/// As [`reference::render`] and [`reference::render_composite`]; `Unsupported` for an inserted
/// shape with no renderer counterpart.
pub fn render_truth(setup: &ComparisonSetup, stereo_views: bool) -> Result<ReferenceTruth> {
    let scene = reference::builtin(&setup.scene)?;
    let options = reference::RenderOptions {
        width: Some(setup.width),
        samples: SampleBudget::PerPixel(setup.samples_per_pixel),
        ..Default::default()
    };
    let inserted: Vec<Object> = setup
        .inserts
        .iter()
        .map(|(name, p, s)| reference::insert_shape(name, *p, *s, 0.0))
        .collect::<Result<_>>()?;
    // Depth, lights and environment are exact per pixel centre: one sample is enough for them,
    // unless the views themselves are wanted.
    let truth_options = if stereo_views {
        options
    } else {
        reference::RenderOptions {
            samples: SampleBudget::PerPixel(1),
            ..options
        }
    };
    let images = reference::render(&scene, &truth_options)?;
    let truth = reference::render_composite(&scene, &inserted, &options)?;
    let lights = images
        .lights
        .iter()
        .map(light_from_record)
        .collect::<Result<Vec<_>>>()?;
    let world_to_camera = Mat4::from_cols_array(&images.camera_to_world).inverse();
    let artefacts = inserted
        .iter()
        .map(|o| artefact_for(o, world_to_camera))
        .collect::<Result<Vec<_>>>()?;
    // The renderer adds the lights itself and has no interreflections: its true ambient is the
    // radiance arriving at the objects from everything but the emitters (walls, floor, sky).
    let sh9 = match setup.inserts.first() {
        Some((_, base, _)) => {
            let at = world_to_camera.transform_point3(Vec3::from(*base) + Vec3::Y * 0.1);
            let probe = reference::radiance_probe(
                &scene,
                &reference::RenderOptions {
                    samples: SampleBudget::PerPixel(16),
                    ..options
                },
                at.to_array(),
                16,
            )?;
            sh9_from_cube(&without_emitters(probe, &images.lights), f32::MAX, 0.0)
        }
        None => sh9_from_equirect(&images.environment),
    };
    Ok(ReferenceTruth {
        photo: truth.background,
        right: stereo_views.then_some(images.right),
        calibration: images.calibration,
        sh9,
        depth: images.depth,
        lights,
        composite: truth.composite,
        mask: truth.mask,
        ratio: truth.ratio,
        artefacts,
        reference_seconds: truth.render_seconds,
        samples_per_pixel: truth.samples_per_pixel,
    })
}

/// The probe with the texels that see an emitter directly set to black: those brighter than half
/// the dimmest area or sphere light's radiance (luminance). A sun or other directional light is
/// never hit by a probe ray, and nothing in the built-in scenes but an emitter comes close to that
/// brightness.
fn without_emitters(mut probe: CubeLevel, lights: &[LightRecord]) -> CubeLevel {
    let luminance = |c: [f32; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
    let dimmest = lights
        .iter()
        .filter_map(|l| l.radiance)
        .map(luminance)
        .fold(f32::INFINITY, f32::min);
    if dimmest.is_finite() {
        for t in &mut probe.texels {
            if luminance(*t) > 0.5 * dimmest {
                *t = [0.0; 3];
            }
        }
    }
    probe
}

/// What [`compare_true_inputs`] measured.
#[derive(Debug, Clone)]
pub struct TrueInputRun {
    /// Per configuration.
    pub rows: Vec<ComparisonRow>,
    /// The composite of the first configuration (its untimed warm-up render); `None` without
    /// configurations.
    pub first: Option<Composite>,
}

/// Renders `truth`'s objects into its photo with TRUE depth (mesh from it), lights and SH9, once
/// per configuration, and measures each against the ground truth. One untimed render first
/// takes the device's first-use cost out of the figures; its composite is kept.
///
/// # Errors
/// As [`SceneMesh::from_depth`] and [`Renderer::render`].
pub fn compare_true_inputs(
    renderer: &Renderer,
    truth: &ReferenceTruth,
    configs: &[RenderOptions],
) -> Result<TrueInputRun> {
    let (w, h) = truth.size();
    let camera =
        Camera::from_calibration(&truth.calibration, w, h)?.with_clip_from_depth(&truth.depth)?;
    let mesh = SceneMesh::from_depth(&truth.depth, &camera, &MeshOptions::default())?;
    let set = truth.artefact_set()?;
    let inputs = RenderInputs {
        photo: &truth.photo,
        camera: &camera,
        scene_mesh: Some(&mesh),
        artefacts: &set,
        lights: &truth.lights,
        sh9: &truth.sh9,
        specular: None,
        photo_shadow: None,
    };
    let first = configs
        .first()
        .map(|config| renderer.render(&inputs, config))
        .transpose()?;
    let mut rows = Vec::new();
    for config in configs {
        let start = Instant::now();
        let out: Composite = renderer.render(&inputs, config)?;
        let render_ms = start.elapsed().as_secs_f64() * 1e3;
        let e = truth.errors(&out.composite, false);
        rows.push(ComparisonRow {
            options: *config,
            image: e.image,
            artefact: e.artefact,
            shadow: e.shadow,
            affected: e.affected,
            render_ms,
        });
    }
    Ok(TrueInputRun { rows, first })
}

/// Renders the setup's scene with the path tracer (photo, TRUE depth and lights, ground-truth
/// composite), then with the renderer in every configuration, and measures the error of each.
///
/// # Errors
/// As [`render_truth`] and [`compare_true_inputs`].
pub fn compare_with_reference(
    renderer: &Renderer,
    setup: &ComparisonSetup,
) -> Result<ComparisonResult> {
    let truth = render_truth(setup, false)?;
    let rows = compare_true_inputs(renderer, &truth, &setup.configs)?.rows;
    Ok(ComparisonResult {
        rows,
        reference_seconds: truth.reference_seconds,
        samples_per_pixel: truth.samples_per_pixel,
        size: truth.size(),
    })
}

/// The comparison as a Markdown table.
pub fn markdown_table(setup: &ComparisonSetup, result: &ComparisonResult) -> String {
    let mut s = format!(
        "Scene `{}` at {}×{}, TRUE depth and lights; reference: {} spp in {:.2} s.\n\n\
         | shading | shadows | map | filter | MAE image | PSNR image | MAE artefact | PSNR artefact | MAE shadow | PSNR shadow | render ms |\n\
         |---|---|---|---|---|---|---|---|---|---|---|\n",
        setup.scene, result.size.0, result.size.1, result.samples_per_pixel, result.reference_seconds
    );
    for r in &result.rows {
        s.push_str(&format!(
            "| {:?} | {:?} | {} | {} | {:.4} | {:.2} | {:.4} | {:.2} | {:.4} | {:.2} | {:.1} |\n",
            r.options.shading,
            r.options.shadows,
            r.options.shadow_map_size,
            r.options.filter_radius,
            r.image.mae,
            r.image.psnr,
            r.artefact.mae,
            r.artefact.psnr,
            r.shadow.mae,
            r.shadow.psnr,
            r.render_ms
        ));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::{GpuContext, GpuOptions, ShadingMode, ShadowMode};

    #[test]
    fn constant_environment_projects_to_its_radiance() {
        let env = Raster::filled(64, 32, [0.25f32, 0.5, 1.0]);
        let sh = sh9_from_equirect(&env);
        for n in [Vec3::X, -Vec3::Y, Vec3::new(0.3, 0.4, -0.866).normalize()] {
            let d = sh.diffuse_radiance(n);
            for (k, want) in [0.25f32, 0.5, 1.0].iter().enumerate() {
                assert!((d[k] - want).abs() < 0.01 * want, "{n}: {d:?}");
            }
        }
    }

    #[test]
    fn ldr_errors_clip_both_sides_and_hdr_errors_neither() {
        // A 2×1 truth: an object pixel at 1.5 (a highlight) and a background pixel at 0.5.
        let composite = Raster::from_vec(2, 1, vec![[1.5f32; 3], [0.5; 3]]);
        let truth = ReferenceTruth {
            photo: Raster::from_vec(2, 1, vec![[0.4f32; 3], [0.5; 3]]),
            right: None,
            calibration: StereoCalibration::from_focal_baseline(100.0, 0.1, 2, 1).unwrap(),
            depth: Raster::filled(2, 1, 2.0),
            lights: Vec::new(),
            sh9: Sh9::default(),
            composite: composite.clone(),
            mask: Raster::from_vec(2, 1, vec![1.0, 0.0]),
            ratio: Raster::filled(2, 1, [1.0f32; 3]),
            artefacts: Vec::new(),
            reference_seconds: 1.0,
            samples_per_pixel: 1,
        };
        // Ours puts the highlight far above white: on a display both are white.
        let ours = Raster::from_vec(2, 1, vec![[20.0f32; 3], [0.5; 3]]);
        let ldr = truth.errors(&ours, true);
        assert_eq!(ldr.artefact.mae, 0.0);
        assert_eq!(ldr.image.mae, 0.0);
        let hdr = truth.errors(&ours, false);
        assert!((hdr.artefact.mae - 18.5).abs() < 1e-6, "{:?}", hdr.artefact);
        // Below white nothing is clipped: a dark object pixel still counts.
        let dark = Raster::from_vec(2, 1, vec![[0.25f32; 3], [0.5; 3]]);
        assert!((truth.errors(&dark, true).artefact.mae - 0.75).abs() < 1e-6);
    }

    #[test]
    fn light_records_become_lights() {
        let rect = LightRecord {
            kind: "rect".into(),
            position: Some([0.0, 1.0, -2.0]),
            normal: Some([0.0, -1.0, 0.0]),
            size: Some([0.5, 0.5]),
            radius: None,
            direction: None,
            angular_diameter_deg: None,
            radiance: Some([1.0; 3]),
            intensity: Some([0.25; 3]),
            power: None,
            irradiance: None,
        };
        let l = light_from_record(&rect).unwrap();
        assert_eq!(l.kind, LightKind::Area);
        // Equal area: π (d/2)² = 0.25.
        assert!((std::f32::consts::PI * (l.size / 2.0).powi(2) - 0.25).abs() < 1e-6);
        let broken = LightRecord {
            intensity: None,
            ..rect
        };
        assert!(light_from_record(&broken)
            .unwrap_err()
            .to_string()
            .contains("intensity"));
    }

    /// `cargo test --release --lib render::compare -- --ignored --nocapture`: the table of the
    /// renderer against the path tracer on `room` (TRUE depth and lights).
    #[test]
    #[ignore]
    fn room_against_the_reference() {
        let gpu = GpuContext::new(&GpuOptions::default()).unwrap();
        let renderer = Renderer::new(&gpu).unwrap();
        let mut configs = Vec::new();
        for shading in [ShadingMode::Pbr, ShadingMode::Thesis] {
            for shadows in [
                ShadowMode::ThesisEsm,
                ShadowMode::Evsm,
                ShadowMode::Pcss,
                ShadowMode::Off,
            ] {
                configs.push(RenderOptions {
                    shading,
                    shadows,
                    ..RenderOptions::default()
                });
            }
        }
        for size in [512, 2048, 4096] {
            configs.push(RenderOptions {
                shadow_map_size: size,
                shadows: ShadowMode::Pcss,
                ..RenderOptions::default()
            });
        }
        for filter_radius in [0, 4, 8] {
            configs.push(RenderOptions {
                filter_radius,
                ..RenderOptions::default()
            });
        }
        let width: u32 = std::env::var("PARALLAX_COMPARE_WIDTH")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(160);
        let setup = ComparisonSetup::room(width, 64, configs);
        let result = compare_with_reference(&renderer, &setup).unwrap();
        println!("{}", markdown_table(&setup, &result));
        for r in &result.rows {
            assert!(r.image.mae.is_finite() && r.artefact.pixels > 0 && r.shadow.pixels > 0);
        }
    }
}
