//! `parallax eval reconstruction`: renders built-in synthetic scenes with the reference path
//! tracer (exact depth, normals and camera pose), reconstructs them through the [`Scene`] (our
//! stereo matcher, mesh, surfaces, placement) and scores the result against the truth: depth and
//! mesh error, normal error over the whole image and on the floor and the table top, plane and
//! up-vector detection, and where an object placed on the floor or the table comes to rest.
//!
//! Writes `reconstruction.md` (the table and how each figure is defined) and `reconstruction.json`
//! (the same figures) to the output folder. With `--options`, each scene is rendered once and
//! reconstructed with the scene's default stereo options and with each set given, so that rows
//! differ only by the options (a render at 256 spp takes minutes).

use std::fmt::Write as _;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use glam::{Mat4, Vec2, Vec3};
use parallax::camera::Camera;
use parallax::context::{Context, ContextOptions};
use parallax::image::{Image, Raster};
use parallax::mesh::{self, PlaceOptions, Surfaces};
use parallax::reference::{self, Images, RenderOptions, SampleBudget, Shape};
use parallax::scene::Scene;
use parallax::stereo::StereoOptions;
use parallax::trace::Trace;
use parallax::{Error, Result};
use rayon::prelude::*;

use crate::common::CommonArgs;

/// Arguments of `parallax eval reconstruction`.
#[derive(clap::Args, Debug)]
pub struct ReconstructionArgs {
    /// Built-in scene to evaluate (repeatable): room, clutter, window, two-lights.
    #[arg(long = "scene", value_name = "NAME", default_values = ["room", "clutter", "window"])]
    scenes: Vec<String>,
    /// Rendered image width, pixels.
    #[arg(long, default_value_t = 480)]
    width: u32,
    /// Rendered image height, pixels.
    #[arg(long, default_value_t = 360)]
    height: u32,
    /// Path-tracing samples per pixel (the noise the matcher sees).
    #[arg(long, default_value_t = 16)]
    spp: u32,
    /// Give the renderer's exact depth to the scene as host depth instead of matching the pair:
    /// separates the reconstruction's own error from the stereo matcher's.
    #[arg(long)]
    true_depth: bool,
    /// Also reconstruct each render with these stereo options: a JSON object of `StereoOptions`
    /// fields (inline, or `@FILE`) over the scene's default (`quality`), `max_disparity` from
    /// the render's calibration unless given (for example `{"smoothing_passes": 0}`). Each set
    /// gives its own rows, `SCENE (options K)`, on the same render. May be given several times.
    #[arg(long, value_name = "JSON|@FILE", conflicts_with = "true_depth")]
    options: Vec<String>,
    /// Where `reconstruction.md` and `reconstruction.json` go.
    #[arg(long, default_value = "target/eval-reconstruction", value_name = "DIR")]
    out: PathBuf,
    #[command(flatten)]
    common: CommonArgs,
}

/// A pixel's surface counts as lying on a true horizontal plane when its true normal is within this
/// angle of the true up …
const PLANE_NORMAL_TOLERANCE_DEG: f32 = 2.0;
/// … and its true point within this distance of the plane, metres.
const PLANE_DISTANCE_TOLERANCE_M: f32 = 0.01;
/// A detected surface matches a true plane when its normal is within this angle of the true up …
const MATCH_NORMAL_DEG: f32 = 10.0;
/// … and its centroid within this distance of the true plane, metres.
const MATCH_DISTANCE_M: f32 = 0.05;
/// Largest side of the object placed in the placement test, metres.
const PLACED_SIZE_M: f32 = 0.1;

/// A true horizontal plane of the scene in the left camera's frame: points `p` on it satisfy
/// `up · p = offset`.
#[derive(Debug, Clone, Copy)]
struct TruePlane {
    name: &'static str,
    offset: f32,
}

/// Median and 90th percentile of a sample; `None` when empty.
#[derive(Debug, Clone, Copy, serde::Serialize)]
struct Spread {
    median: f64,
    p90: f64,
    count: usize,
}

fn spread(mut values: Vec<f64>) -> Option<Spread> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    let rank =
        |q: f64| values[((q * values.len() as f64).ceil() as usize).clamp(1, values.len()) - 1];
    Some(Spread {
        median: rank(0.5),
        p90: rank(0.9),
        count: values.len(),
    })
}

/// How well one true plane was recovered.
#[derive(Debug, Clone, serde::Serialize)]
struct PlaneResult {
    plane: &'static str,
    /// The plane's height along the true up relative to the camera, metres.
    height_m: f64,
    /// Pixels of the plane seen in the left view.
    pixels: usize,
    /// Angle between the mesh's normal and the true normal over those pixels, degrees.
    normal_error_deg: Option<Spread>,
    /// The detected surface matching the plane: its normal error (degrees) and offset error
    /// (metres), `None` when no surface matches.
    detected_normal_error_deg: Option<f64>,
    detected_offset_error_m: Option<f64>,
    /// Placement at the plane's most interior pixel: base height error relative to the true
    /// distance of the surface point there (signed, fraction), and the pixel used.
    placement_height_error: Option<f64>,
    placement_pixel: Option<[f32; 2]>,
    placement_failure: Option<String>,
}

/// Everything measured on one scene.
#[derive(Debug, Clone, serde::Serialize)]
struct SceneResult {
    scene: String,
    /// The `--options` set the scene was reconstructed with (`None`: the scene's default).
    options: Option<String>,
    width: u32,
    height: u32,
    spp: u32,
    /// Median over the left view's pixels of the renderer's standard error of the pixel's
    /// luminance relative to the luminance: how noisy the pair the matcher sees is. `None` with
    /// one sample per pixel (no variance).
    render_noise: Option<f64>,
    render_s: f64,
    reconstruct_s: f64,
    /// Relative error |Z − Z*|/Z* of the scene's depth map (stereo) over pixels with both.
    depth_error: Option<Spread>,
    /// Relative error of the mesh's depth (a pick at each pixel centre) over pixels with both.
    mesh_error: Option<Spread>,
    /// Pixels with true depth whose pick hit the mesh, fraction.
    mesh_coverage: f64,
    /// Angle between the mesh's normal at the pick and the true normal over every pixel with
    /// both (planes, objects and edges alike), degrees.
    normal_error_deg: Option<Spread>,
    up_error_deg: f64,
    up_source: String,
    planes: Vec<PlaneResult>,
    /// Every detected surface, largest first, against the truth.
    surfaces: Vec<SurfaceSummary>,
}

/// One detected surface seen against the truth.
#[derive(Debug, Clone, serde::Serialize)]
struct SurfaceSummary {
    kind: String,
    inliers: usize,
    /// Angle between its normal and the true up, degrees.
    tilt_deg: f64,
    /// Its centroid's height along the true up, relative to the camera, metres.
    height_m: f64,
    area_m2: f64,
}

/// Dispatches `parallax eval reconstruction`.
pub fn run(args: ReconstructionArgs) -> Result<()> {
    let mut trace = Trace::new();
    for name in &args.scenes {
        if !reference::BUILTIN_SCENES.contains(&name.as_str()) {
            return Err(Error::invalid(format!(
                "--scene {name:?}: not a built-in scene ({})",
                reference::BUILTIN_SCENES.join(", ")
            )));
        }
    }
    if args.spp == 0 {
        return Err(Error::invalid("--spp must be at least 1"));
    }
    // Every set is checked before the first (long) render.
    let mut configs: Vec<Option<OptionsSet>> = vec![None];
    for spec in &args.options {
        configs.push(Some(OptionsSet::parse(spec)?));
    }
    std::fs::create_dir_all(&args.out).map_err(|e| Error::io(&args.out, e))?;
    let context = Arc::new(Context::new(ContextOptions::default())?);
    let mut results = Vec::new();
    for name in &args.scenes {
        let spinner = args.common.spinner(&format!("{name}: rendering"));
        let (images, render_s) = trace.time(name, "render", |_| render(name, &args))?;
        for (k, config) in configs.iter().enumerate() {
            let label = match config {
                None => name.clone(),
                Some(_) => format!("{name} (options {k})"),
            };
            let result = trace.time(&label, "reconstruct and score", |_| {
                evaluate(
                    &label,
                    (&images, render_s),
                    config.as_ref(),
                    &args,
                    &context,
                )
            })?;
            results.push(result);
        }
        spinner.finish_and_clear();
    }
    let markdown = markdown(&results, &args);
    print!("{markdown}");
    let md_path = args.out.join("reconstruction.md");
    std::fs::write(&md_path, &markdown).map_err(|e| Error::io(&md_path, e))?;
    let json_path = args.out.join("reconstruction.json");
    let json = serde_json::to_string_pretty(&results)
        .map_err(|e| Error::Internal(format!("reconstruction.json: {e}")))?;
    std::fs::write(&json_path, json).map_err(|e| Error::io(&json_path, e))?;
    args.common.finish(&trace)
}

/// World height of the top of each horizontal support the scene description names (the floor
/// plane and the table top), when the object is unrotated (else its top is not horizontal in a
/// way this evaluation can read off the description).
fn true_plane_heights(images: &Images) -> Vec<(&'static str, f32)> {
    let mut planes = Vec::new();
    for object in &images.scene.objects {
        let t = &object.transform;
        if t.rotation_deg != [0.0; 3] {
            continue;
        }
        match (object.name.as_str(), &object.shape) {
            ("floor", Shape::Plane { .. }) => planes.push(("floor", t.translation[1])),
            ("table top", Shape::Box { size }) => {
                planes.push(("table", t.translation[1] + 0.5 * size[1] * t.scale[1]))
            }
            _ => {}
        }
    }
    planes
}

fn angle_deg(a: Vec3, b: Vec3) -> f32 {
    a.normalize_or_zero()
        .dot(b.normalize_or_zero())
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

/// One `--options` set.
struct OptionsSet {
    /// As given on the command line.
    spec: String,
    /// The set over the scene's default options.
    options: StereoOptions,
    /// `max_disparity` when the set names it; else the render's calibration gives it.
    max_disparity: Option<u32>,
}

impl OptionsSet {
    /// Parses and checks `spec` (inline JSON or `@FILE`).
    ///
    /// # Errors
    /// `InvalidArgument` naming the spec for malformed JSON, an unknown field or a value out of
    /// range; `Io` for an unreadable file.
    fn parse(spec: &str) -> Result<OptionsSet> {
        let text = crate::common::options_text(spec)?;
        let options = Scene::default_stereo_options().with_json(&text)?;
        let named = serde_json::from_str::<serde_json::Value>(&text)
            .is_ok_and(|v| v.get("max_disparity").is_some());
        let max_disparity = named.then_some(options.max_disparity);
        let mut checked = options.clone();
        checked.max_disparity = max_disparity.unwrap_or(1);
        // `with_json`'s errors name the JSON; the range check's do not.
        checked.validate(u32::MAX).map_err(|e| match e {
            Error::InvalidArgument(why) => Error::invalid(format!("--options {spec:?}: {why}")),
            other => other,
        })?;
        Ok(OptionsSet {
            spec: spec.to_string(),
            options,
            max_disparity,
        })
    }
}

/// The built-in scene `name` rendered at the arguments' size and sample count, and the seconds
/// it took.
fn render(name: &str, args: &ReconstructionArgs) -> Result<(Images, f64)> {
    let start = Instant::now();
    let images = reference::render(
        &reference::builtin(name)?,
        &RenderOptions {
            width: Some(args.width),
            height: Some(args.height),
            samples: SampleBudget::PerPixel(args.spp),
            ..RenderOptions::default()
        },
    )?;
    Ok((images, start.elapsed().as_secs_f64()))
}

/// Reconstructs one render (and the seconds it took) through the `Scene`, with an `--options`
/// set when given, and scores it; `row` names the result.
fn evaluate(
    row: &str,
    (images, render_s): (&Images, f64),
    config: Option<&OptionsSet>,
    args: &ReconstructionArgs,
    context: &Arc<Context>,
) -> Result<SceneResult> {
    let (w, h) = (images.depth.width(), images.depth.height());

    // The truth in the left camera's frame (x right, y up, z towards the viewer).
    let camera_to_world = Mat4::from_cols_array(&images.camera_to_world);
    let world_to_camera = camera_to_world.inverse();
    let world_up = Vec3::from(images.scene.camera.up).normalize();
    let up = world_to_camera.transform_vector3(world_up).normalize();
    let eye_height = world_up.dot(camera_to_world.w_axis.truncate());
    let planes: Vec<TruePlane> = true_plane_heights(images)
        .into_iter()
        .map(|(name, height)| TruePlane {
            name,
            offset: height - eye_height,
        })
        .collect();
    let true_camera = Camera::from_calibration(&images.calibration, w as u32, h as u32)?;
    let true_point = |x: usize, y: usize| {
        true_camera.unproject(x as f32 + 0.5, y as f32 + 0.5, *images.depth.get(x, y))
    };
    // Which true plane each pixel shows (index into `planes`).
    let label = Raster::from_fn(w, h, |x, y| {
        let n = Vec3::from(*images.normals.get(x, y));
        let p = true_point(x, y)?;
        if n.length() < 0.5 || angle_deg(n, up) > PLANE_NORMAL_TOLERANCE_DEG {
            return None;
        }
        planes
            .iter()
            .position(|pl| (up.dot(p) - pl.offset).abs() < PLANE_DISTANCE_TOLERANCE_M)
    });

    // Reconstruction through the Scene, as a host would run it.
    let start = Instant::now();
    let mut scene = Scene::new(context.clone());
    let left = Image::from_linear_rgb(&images.left);
    let right = Image::from_linear_rgb(&images.right);
    scene.set_stereo_pair(&left.view(), &right.view())?;
    scene.set_calibration(images.calibration)?;
    if let Some(set) = config {
        scene.set_stereo_options_auto_range(set.options.clone(), set.max_disparity)?;
    }
    if args.true_depth {
        scene.set_depth(images.depth.clone(), None, None)?;
    }
    let depth = scene.depth()?;
    let bvh = scene.bvh()?;
    let camera = scene.camera()?;
    let surfaces = scene.surfaces()?;
    let reconstruct_s = start.elapsed().as_secs_f64();

    // Per pixel: (depth rel. error, mesh rel. error, has truth, mesh hit, plane, normal error).
    type PixelScore = (
        Option<f64>,
        Option<f64>,
        bool,
        bool,
        Option<usize>,
        Option<f64>,
    );
    let scores: Vec<PixelScore> = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let truth = *images.depth.get(x, y);
            if !(truth.is_finite() && truth > 0.0) {
                return (None, None, false, false, None, None);
            }
            let d = *depth.get(x, y);
            let depth_err = (d.is_finite() && d > 0.0).then(|| ((d - truth) / truth).abs() as f64);
            let hit = mesh::pick(&bvh, &camera, Vec2::new(x as f32 + 0.5, y as f32 + 0.5));
            let mesh_err = hit
                .as_ref()
                .map(|hit| ((-hit.point.z - truth) / truth).abs() as f64);
            let plane = *label.get(x, y);
            let true_normal = Vec3::from(*images.normals.get(x, y));
            let normal_err = match &hit {
                Some(hit) if true_normal.length() > 0.5 => {
                    Some(angle_deg(hit.normal, true_normal) as f64)
                }
                _ => None,
            };
            (depth_err, mesh_err, true, hit.is_some(), plane, normal_err)
        })
        .collect();
    let with_truth = scores.iter().filter(|s| s.2).count();
    let with_hit = scores.iter().filter(|s| s.3).count();

    let plane_results = planes
        .iter()
        .enumerate()
        .map(|(k, plane)| {
            let pixels = scores.iter().filter(|s| s.4 == Some(k)).count();
            let normal_error_deg = spread(
                scores
                    .iter()
                    .filter(|s| s.4 == Some(k))
                    .filter_map(|s| s.5)
                    .collect(),
            );
            let detected = best_match(&surfaces, up, plane);
            let mut result = PlaneResult {
                plane: plane.name,
                height_m: plane.offset as f64,
                pixels,
                normal_error_deg,
                detected_normal_error_deg: detected
                    .map(|s| angle_deg(surfaces.surfaces[s].normal, up) as f64),
                detected_offset_error_m: detected.map(|s| {
                    let surface = &surfaces.surfaces[s];
                    // Offsets compare only along a common normal: measure the centroid's height.
                    (up.dot(surface.centroid) - plane.offset) as f64
                }),
                placement_height_error: None,
                placement_pixel: None,
                placement_failure: None,
            };
            match interior_pixel(&label, k) {
                None => result.placement_failure = Some("plane not visible".into()),
                Some((x, y)) => {
                    let pixel = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                    result.placement_pixel = Some(pixel.to_array());
                    let truth = true_point(x, y);
                    match (
                        scene.place(pixel, PLACED_SIZE_M, 0.0, &PlaceOptions::default()),
                        truth,
                    ) {
                        (Ok(placed), Some(p)) => {
                            result.placement_height_error =
                                Some((up.dot(placed.base - p) / p.length()) as f64)
                        }
                        (Err(e), _) => result.placement_failure = Some(e.to_string()),
                        (_, None) => result.placement_failure = Some("no true depth".into()),
                    }
                }
            }
            result
        })
        .collect();

    Ok(SceneResult {
        scene: row.to_string(),
        options: config.map(|set| set.spec.clone()),
        width: w as u32,
        height: h as u32,
        spp: args.spp,
        render_noise: images.median_relative_noise(),
        render_s,
        reconstruct_s,
        depth_error: spread(scores.iter().filter_map(|s| s.0).collect()),
        mesh_error: spread(scores.iter().filter_map(|s| s.1).collect()),
        mesh_coverage: with_hit as f64 / with_truth.max(1) as f64,
        normal_error_deg: spread(scores.iter().filter_map(|s| s.5).collect()),
        up_error_deg: angle_deg(surfaces.up, up) as f64,
        up_source: format!("{:?}", surfaces.up_source),
        planes: plane_results,
        surfaces: surfaces
            .surfaces
            .iter()
            .map(|s| SurfaceSummary {
                kind: format!("{:?}", s.kind),
                inliers: s.inliers,
                tilt_deg: angle_deg(s.normal, up) as f64,
                height_m: up.dot(s.centroid) as f64,
                area_m2: s.area_m2 as f64,
            })
            .collect(),
    })
}

/// The detected surface that matches `plane` (normal within [`MATCH_NORMAL_DEG`] of the true up,
/// centroid within [`MATCH_DISTANCE_M`] of the plane); the one with most inliers when several do.
fn best_match(surfaces: &Surfaces, up: Vec3, plane: &TruePlane) -> Option<usize> {
    surfaces
        .surfaces
        .iter()
        .enumerate()
        .filter(|(_, s)| {
            angle_deg(s.normal, up) < MATCH_NORMAL_DEG
                && (up.dot(s.centroid) - plane.offset).abs() < MATCH_DISTANCE_M
        })
        .max_by_key(|(_, s)| s.inliers)
        .map(|(i, _)| i)
}

/// The pixel of plane `k` farthest inside its region: the region is eroded (3×3) until one more
/// step would empty it, and of what is left the pixel nearest its centre is taken. Placing there
/// keeps the test off the plane's edges, where the footprint would hang over.
fn interior_pixel(label: &Raster<Option<usize>>, k: usize) -> Option<(usize, usize)> {
    let (w, h) = (label.width(), label.height());
    let mut mask = Raster::from_fn(w, h, |x, y| *label.get(x, y) == Some(k));
    let mut last: Vec<(usize, usize)> = Vec::new();
    loop {
        let inside: Vec<(usize, usize)> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .filter(|&(x, y)| *mask.get(x, y))
            .collect();
        if inside.is_empty() {
            break;
        }
        last = inside;
        mask = Raster::from_fn(w, h, |x, y| {
            (x > 0 && y > 0 && x + 1 < w && y + 1 < h)
                && (y - 1..=y + 1).all(|yy| (x - 1..=x + 1).all(|xx| *mask.get(xx, yy)))
        });
    }
    let n = last.len() as f64;
    if n == 0.0 {
        return None;
    }
    let cx = last.iter().map(|p| p.0 as f64).sum::<f64>() / n;
    let cy = last.iter().map(|p| p.1 as f64).sum::<f64>() / n;
    last.into_iter().min_by(|a, b| {
        let da = (a.0 as f64 - cx).powi(2) + (a.1 as f64 - cy).powi(2);
        let db = (b.0 as f64 - cx).powi(2) + (b.1 as f64 - cy).powi(2);
        da.total_cmp(&db)
    })
}

/// The columns of the results table (also checked by the tests).
pub const COLUMNS: [&str; 13] = [
    "scene",
    "render noise (median σ/L)",
    "depth rel. err. median / p90",
    "mesh rel. err. median / p90",
    "mesh coverage",
    "normal err. median / p90, all pixels (°)",
    "floor normal err. median (°)",
    "table normal err. median (°)",
    "floor plane normal err. (°)",
    "table plane normal err. (°)",
    "up err. (°)",
    "floor placement height err. (% dist.)",
    "table placement height err. (% dist.)",
];

fn markdown(results: &[SceneResult], args: &ReconstructionArgs) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Reconstruction accuracy on synthetic scenes\n\n\
         Reference renders at {}×{}, {} spp; depth {} through `Scene`.\n",
        args.width,
        args.height,
        args.spp,
        if args.true_depth {
            "= the renderer's exact depth, given as host depth (no stereo)"
        } else {
            "from our stereo matcher (default options)"
        }
    );
    let _ = writeln!(s, "| {} |", COLUMNS.join(" | "));
    let _ = writeln!(s, "|{}", "---|".repeat(COLUMNS.len()));
    let pct = |v: Option<Spread>| match v {
        Some(v) => format!("{:.2} % / {:.2} %", 100.0 * v.median, 100.0 * v.p90),
        None => "—".into(),
    };
    for r in results {
        let plane = |name: &str| r.planes.iter().find(|p| p.plane == name);
        let normal = |name: &str| match plane(name).and_then(|p| p.normal_error_deg) {
            Some(v) => format!("{:.2}", v.median),
            None => "—".into(),
        };
        let detected = |name: &str| match plane(name) {
            None => "— (no such plane)".into(),
            Some(p) => match p.detected_normal_error_deg {
                Some(v) => format!("{v:.2}"),
                None => "not found".into(),
            },
        };
        let placed = |name: &str| match plane(name) {
            None => "— (no such plane)".into(),
            Some(p) => match p.placement_height_error {
                Some(v) => format!("{:+.2}", 100.0 * v),
                None => format!(
                    "failed: {}",
                    p.placement_failure.as_deref().unwrap_or("unknown")
                ),
            },
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:.1} % | {} | {} | {} | {} | {} | {:.2} | {} | {} |",
            r.scene,
            r.render_noise
                .map_or("—".into(), |v| format!("{:.1} %", 100.0 * v)),
            pct(r.depth_error),
            pct(r.mesh_error),
            100.0 * r.mesh_coverage,
            match r.normal_error_deg {
                Some(v) => format!("{:.2} / {:.2}", v.median, v.p90),
                None => "—".into(),
            },
            normal("floor"),
            normal("table"),
            detected("floor"),
            detected("table"),
            r.up_error_deg,
            placed("floor"),
            placed("table"),
        );
    }
    if !args.options.is_empty() {
        let _ = writeln!(
            s,
            "\nRows `(options K)`: the same render reconstructed with the K-th `--options` set \
             over the scene's default stereo options:\n"
        );
        for (k, spec) in args.options.iter().enumerate() {
            let _ = writeln!(s, "- options {}: `{spec}`", k + 1);
        }
    }
    let _ = writeln!(s, "\n## Details\n");
    for r in results {
        let _ = writeln!(
            s,
            "- **{}**: render {:.1} s, reconstruction (stereo, mesh, BVH, surfaces) {:.1} s; up from {}.",
            r.scene, r.render_s, r.reconstruct_s, r.up_source
        );
        for p in &r.planes {
            let _ = writeln!(
                s,
                "  - {} (height {:+.2} m): {} px; mesh normal err. {}; detected plane height err. {}; placement at {} → {}",
                p.plane,
                p.height_m,
                p.pixels,
                p.normal_error_deg
                    .map(|v| format!("median {:.2}° / p90 {:.2}° over {} px", v.median, v.p90, v.count))
                    .unwrap_or_else(|| "—".into()),
                p.detected_offset_error_m
                    .map(|v| format!("{:+.1} mm", 1000.0 * v))
                    .unwrap_or_else(|| "—".into()),
                p.placement_pixel
                    .map(|q| format!("({:.1}, {:.1})", q[0], q[1]))
                    .unwrap_or_else(|| "—".into()),
                p.placement_height_error
                    .map(|v| format!("height err. {:+.3} % of distance", 100.0 * v))
                    .or_else(|| p.placement_failure.clone())
                    .unwrap_or_default(),
            );
        }
    }
    let _ = writeln!(s, "\n## Detected surfaces\n");
    for r in results {
        let list: Vec<String> = r
            .surfaces
            .iter()
            .map(|x| {
                format!(
                    "{} {} pts, tilt {:.1}°, height {:+.2} m, {:.2} m²",
                    x.kind.to_lowercase(),
                    x.inliers,
                    x.tilt_deg,
                    x.height_m,
                    x.area_m2
                )
            })
            .collect();
        let _ = writeln!(s, "- **{}**: {}", r.scene, list.join("; "));
    }
    let _ = writeln!(
        s,
        "\n## Definitions\n\n\
         - Render noise: the path tracer's standard error of each left pixel's luminance \
         (`variance0.pfm` of `parallax synth`), relative to the pixel's luminance; median over \
         the pixels (— with one sample per pixel). The right view carries independent noise of \
         the same size.\n\
         - Relative error: |Z − Z*| / Z* per pixel with true depth Z* and an estimate Z (the depth \
         map's value; for the mesh, the depth of a pick at the pixel centre); median and 90th \
         percentile over those pixels. Coverage: pixels with true depth whose pick hits the mesh.\n\
         - Normal error, all pixels: angle between the mesh's smooth normal at the pick and the \
         true normal, over every pixel with true depth, a true normal and a hit (planes, objects \
         and edges alike).\n\
         - Floor / table pixels: true normal within {PLANE_NORMAL_TOLERANCE_DEG}° of the true up \
         and true point within {} cm of the plane (heights from the scene description). Normal \
         error: angle between the mesh's smooth normal at the pick and the true normal.\n\
         - True up: the rig's world up expressed in the left camera frame (inverse of \
         `camera_to_world`). Up err.: angle to `Surfaces::up`.\n\
         - Plane detection: a detected surface matches a true plane when its normal is within \
         {MATCH_NORMAL_DEG}° of the true up and its centroid within {} cm of the plane (most \
         inliers wins); its error is the angle between its normal and the true up. \"not found\" = \
         no surface matches.\n\
         - Detected surfaces: kind, inliers, tilt = angle between the surface's normal and the \
         true up, height = true up · centroid (the camera is at 0; compare with the true planes' \
         heights in the details).\n\
         - Placement: an object of {} m placed (default options) at the plane's most interior \
         pixel; error = (true up · (base − true point at that pixel)) / distance of the true point, \
         signed (+ = above the surface).",
        100.0 * PLANE_DISTANCE_TOLERANCE_M,
        100.0 * MATCH_DISTANCE_M,
        PLACED_SIZE_M,
    );
    s
}
