//! The reference: a physically based CPU path tracer and synthetic stereo scenes with exact truth.
//!
//! It serves as ground truth for every stage (stereo pairs with exact disparity, depth, normals,
//! the true lights and per-light shadow masks), as the yardstick for the real-time renderer (the
//! same scene and materials rendered with exact visibility, see [`render_composite`]), and as the
//! embedded default scene of the demo (no downloaded data needed).
//!
//! - [`Scene`]: the description (serde/JSON): a rectified stereo rig, objects with glTF
//!   metallic-roughness materials and procedural textures, rect/sphere/directional lights, an
//!   environment, and [`Portal`]s (openings that distant light is sampled through). [`builtin`]
//!   gives the built-in scenes ([`BUILTIN_SCENES`]).
//! - [`render`]: both views by path tracing (next-event estimation with multiple importance
//!   sampling, portals, Russian roulette, obvhs CWBVH), plus the ground truth → [`Images`], which
//!   [`Images::write_middlebury_layout`] writes as a Middlebury folder.
//! - [`render_composite`]: the left view with and without inserted objects → [`Composite`];
//!   `insert_artefact` (feature `gltf`) turns a loaded glTF artefact into such objects.
//!
//! Images are deterministic: the same scene, options and sample count give the same pixels
//! whatever the number of threads (each pixel sample has its own seeded generator).

#[cfg(feature = "gltf")]
mod artefact_insert;
mod brdf;
mod builtin;
mod composite;
mod description;
mod geometry;
mod integrator;
mod lights;
mod outputs;
mod portals;
mod probe;
mod sampling;
mod shapes;
mod textures;

#[cfg(feature = "gltf")]
pub use artefact_insert::insert_artefact;
pub use builtin::{builtin, BUILTIN_SCENES};
pub use composite::{insert_shape, render_composite, Composite, INSERT_SHAPES};
pub use description::{
    CameraRig, Environment, Light, Material, Object, Pattern, Portal, Scene, Shape, Texture,
    Transform, MAX_SEGMENTS,
};
pub use geometry::MAX_TRIANGLES;
pub use outputs::{Images, LightRecord, RenderStats, ENVIRONMENT_SIZE};
pub use probe::radiance_probe;

use glam::Vec3A;
use std::time::{Duration, Instant};

use crate::camera::StereoCalibration;
use crate::error::{Error, Result};
use crate::image::{ImageLimits, Raster};
use integrator::{Camera, PixelSums, RayCounts, ShadowSums, Tracer};

/// How many samples to take per pixel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SampleBudget {
    /// Exactly this many samples per pixel (≥ 1).
    PerPixel(u32),
    /// As many samples as fit into this wall-clock time (at least one), the same number for
    /// every pixel; the count taken is reported in [`RenderStats::samples_per_pixel`].
    Time(Duration),
}

/// The most samples per pixel a render takes.
pub const MAX_SAMPLES_PER_PIXEL: u32 = 1 << 20;

/// How to render.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderOptions {
    /// Output width in pixels; `None` keeps the scene's. Changing the width keeps the horizontal
    /// field of view (the focal length scales with it).
    pub width: Option<u32>,
    /// Output height in pixels; `None` keeps the aspect ratio of the scene's rig.
    pub height: Option<u32>,
    /// Samples per pixel or a time budget.
    pub samples: SampleBudget,
    /// Most surface interactions on a path (1 = direct light only; 0 = emitters seen directly).
    pub max_bounces: u32,
    /// Seed of every pixel's random numbers.
    pub seed: u64,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            width: None,
            height: None,
            samples: SampleBudget::PerPixel(16),
            max_bounces: 8,
            seed: 0,
        }
    }
}

/// The rig at the requested size.
fn resolved_rig(scene: &Scene, options: &RenderOptions) -> Result<(Camera, Scene)> {
    scene.validate()?;
    let rig = &scene.camera;
    let width = options.width.unwrap_or(rig.width);
    let height = options.height.unwrap_or_else(|| {
        if options.width.is_some() {
            ((width as f64 * rig.height as f64 / rig.width as f64).round() as u32).max(1)
        } else {
            rig.height
        }
    });
    ImageLimits::default().check("reference render", width as u64, height as u64)?;
    let focal = rig.focal_px() * width as f64 / rig.width as f64;
    let mut resolved = scene.clone();
    resolved.camera.width = width;
    resolved.camera.height = height;
    resolved.camera.focal_px = Some(focal);
    resolved.camera.fov_x_deg = None;
    let position = Vec3A::from(rig.position);
    let forward = (Vec3A::from(rig.look_at) - position).normalize();
    let right = forward.cross(Vec3A::from(rig.up)).normalize();
    let up = right.cross(forward);
    let camera = Camera {
        eyes: [position, position + right * rig.baseline_m as f32],
        right,
        up,
        forward,
        focal,
        cx: width as f64 / 2.0,
        cy: height as f64 / 2.0,
        width: width as usize,
        height: height as usize,
        baseline: rig.baseline_m,
    };
    Ok((camera, resolved))
}

fn validate_options(options: &RenderOptions) -> Result<()> {
    match options.samples {
        SampleBudget::PerPixel(n) if n == 0 || n > MAX_SAMPLES_PER_PIXEL => Err(Error::invalid(
            format!("samples per pixel must be in 1..={MAX_SAMPLES_PER_PIXEL}, got {n}"),
        )),
        SampleBudget::Time(t) if t.is_zero() => {
            Err(Error::invalid("time budget must be > 0".to_string()))
        }
        _ => Ok(()),
    }?;
    if options.max_bounces > 1024 {
        return Err(Error::invalid(format!(
            "max_bounces must be at most 1024, got {}",
            options.max_bounces
        )));
    }
    Ok(())
}

/// Builds the tracer for `scene` plus extra (inserted) objects.
pub(crate) fn build_tracer(
    scene: &Scene,
    camera: Camera,
    inserted: &[Object],
    max_bounces: u32,
) -> Result<Tracer> {
    let objects: Vec<(&Object, bool)> = scene
        .objects
        .iter()
        .map(|o| (o, false))
        .chain(inserted.iter().map(|o| (o, true)))
        .collect();
    Ok(Tracer {
        geometry: geometry::Geometry::build(&objects)?,
        emitters: scene.lights.iter().map(lights::Emitter::new).collect(),
        env: lights::EnvLight::new(&scene.environment)?,
        portals: portals::Portals::new(&scene.portals),
        camera,
        max_bounces,
    })
}

/// Accumulated samples of one view.
pub(crate) struct ViewSums {
    pub pixels: Vec<PixelSums>,
    pub shadow: Option<Vec<ShadowSums>>,
}

impl ViewSums {
    pub(crate) fn new(tracer: &Tracer, with_shadow: bool) -> ViewSums {
        let n = tracer.camera.width * tracer.camera.height;
        ViewSums {
            pixels: vec![PixelSums::default(); n],
            shadow: with_shadow.then(|| vec![[0.0; 2]; n * tracer.light_count()]),
        }
    }

    pub(crate) fn mean(&self, camera: &Camera, samples: u32) -> Raster<[f32; 3]> {
        let k = 1.0 / samples as f64;
        Raster::from_vec(
            camera.width,
            camera.height,
            self.pixels
                .iter()
                .map(|p| p.rgb.map(|c| (c * k) as f32))
                .collect(),
        )
    }
}

/// Renders `views` (each with its own sums) until the budget is spent; returns the sample count
/// and the ray counts.
pub(crate) fn accumulate(
    tracer: &Tracer,
    views: &mut [(usize, &mut ViewSums)],
    options: &RenderOptions,
) -> (u32, RayCounts) {
    let mut counts = RayCounts::default();
    let mut pass = |first: u32, last: u32, views: &mut [(usize, &mut ViewSums)]| {
        for (view, sums) in views.iter_mut() {
            counts = counts
                + tracer.render_pass(
                    *view,
                    options.seed,
                    first,
                    last,
                    &mut sums.pixels,
                    sums.shadow.as_deref_mut(),
                );
        }
    };
    let taken = match options.samples {
        SampleBudget::PerPixel(n) => {
            pass(0, n, views);
            n
        }
        SampleBudget::Time(budget) => {
            let start = Instant::now();
            let mut taken = 0u32;
            let mut batch = 1u32;
            loop {
                let before = Instant::now();
                pass(taken, taken + batch, views);
                taken += batch;
                let per_sample = before.elapsed().as_secs_f64() / batch as f64;
                let left = budget.as_secs_f64() - start.elapsed().as_secs_f64();
                if per_sample <= 0.0 || left < per_sample || taken >= MAX_SAMPLES_PER_PIXEL {
                    break;
                }
                // Grow batches geometrically but never past what the remaining time allows.
                let fits = (left / per_sample).floor() as u64;
                batch = (batch as u64 * 2)
                    .min(fits)
                    .min((MAX_SAMPLES_PER_PIXEL - taken) as u64)
                    .max(1) as u32;
            }
            taken
        }
    };
    (taken, counts)
}

/// Renders both views of `scene` and its ground truth.
///
/// # Errors
/// `InvalidArgument` for an invalid scene or options (the message names the field), `TooLarge`
/// over the image cap or [`MAX_TRIANGLES`], `Io`/`Format` when an environment map cannot be read.
pub fn render(scene: &Scene, options: &RenderOptions) -> Result<Images> {
    validate_options(options)?;
    let (camera, resolved) = resolved_rig(scene, options)?;
    let build_start = Instant::now();
    let tracer = build_tracer(&resolved, camera, &[], options.max_bounces)?;
    let build_seconds = build_start.elapsed().as_secs_f64();

    let render_start = Instant::now();
    let (truth, truth_counts) = tracer.ground_truth();
    let mut left = ViewSums::new(&tracer, true);
    let mut right = ViewSums::new(&tracer, false);
    let (spp, counts) = accumulate(&tracer, &mut [(0, &mut left), (1, &mut right)], options);
    let render_seconds = render_start.elapsed().as_secs_f64();
    let counts = counts + truth_counts;

    let (w, h) = (camera.width, camera.height);
    let fb = camera.focal * camera.baseline;
    let depth = Raster::from_vec(w, h, truth.iter().map(|t| t.depth as f32).collect());
    let disparity = Raster::from_vec(
        w,
        h,
        truth
            .iter()
            .map(|t| {
                if t.depth.is_nan() {
                    f32::NAN
                } else {
                    (fb / t.depth) as f32
                }
            })
            .collect(),
    );
    let nonocc = Raster::from_vec(
        w,
        h,
        truth
            .iter()
            .map(|t| match (t.depth.is_nan(), t.visible_right) {
                (true, _) => 0,
                (false, true) => 255,
                (false, false) => 128,
            })
            .collect(),
    );
    let normals = Raster::from_vec(w, h, truth.iter().map(|t| t.normal.to_array()).collect());
    let nl = tracer.light_count();
    let shadow_sums = left.shadow.as_deref().unwrap_or(&[]);
    let shadow = (0..nl)
        .map(|i| {
            Raster::from_vec(
                w,
                h,
                (0..w * h)
                    .map(|p| {
                        if truth[p].depth.is_nan() {
                            return 1.0;
                        }
                        let [vis, total] = shadow_sums[p * nl + i];
                        if total > 0.0 {
                            (vis / total).clamp(0.0, 1.0) as f32
                        } else {
                            0.0
                        }
                    })
                    .collect(),
            )
        })
        .collect();
    let variance = (spp >= 2).then(|| {
        let n = spp as f64;
        Raster::from_vec(
            w,
            h,
            left.pixels
                .iter()
                .map(|p| {
                    let mean = p.luminance / n;
                    let var = ((p.luminance_sq / n - mean * mean) * n / (n - 1.0)).max(0.0);
                    (var / n) as f32
                })
                .collect(),
        )
    });
    let calibration = StereoCalibration {
        focal_px: camera.focal,
        cx: camera.cx,
        cy: camera.cy,
        baseline_m: camera.baseline,
        doffs: 0.0,
        // As the pair's calib.txt says (`ndisp`), so that a host given this calibration searches
        // the range the file would give it.
        max_disparity: Some(outputs::DisparityRange::of(&disparity).ndisp),
    };
    let rays = counts.closest + counts.shadow;
    Ok(Images {
        lights: resolved
            .lights
            .iter()
            .map(|l| LightRecord::new(l, &camera))
            .collect(),
        environment: outputs::environment_map(&tracer.env, &camera),
        camera_to_world: outputs::camera_to_world(&camera),
        scene: resolved,
        calibration,
        left: left.mean(&camera, spp),
        right: right.mean(&camera, spp),
        disparity,
        depth,
        nonocc,
        normals,
        shadow,
        variance,
        stats: RenderStats {
            samples_per_pixel: spp,
            triangles: tracer.geometry.triangle_count(),
            build_seconds,
            render_seconds,
            rays: counts.closest,
            shadow_rays: counts.shadow,
            rays_per_second: if render_seconds > 0.0 {
                rays as f64 / render_seconds
            } else {
                0.0
            },
        },
    })
}

#[cfg(test)]
mod tests;
