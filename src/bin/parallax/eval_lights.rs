//! `parallax eval lights`: renders built-in synthetic scenes with the reference path tracer and
//! scores the illumination estimate against the truth: shadow-mask IoU (thesis method and the
//! chromaticity method), main-light direction error, in-view light position error, lights found,
//! SH irradiance error at the insertion point (against a path-traced radiance probe), and the
//! shading error of the fitted model on the photo's surfaces.
//!
//! The photo given to the estimator is the left view clipped to [0, 1] (an LDR photo). Depth,
//! normals and up are the renderer's exact ones; `--stereo` runs the whole `Scene` instead, as a
//! host gets it, on the pair stored as 8-bit sRGB (stereo depth, normals snapped to its support
//! planes, its own up). Writes `lights.md` and `lights.json` to the output folder.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use glam::{Mat4, Vec3};
use parallax::camera::Camera;
use parallax::image::Raster;
use parallax::light::{
    self, cube_direction, cube_texel, estimate_lighting, luminance, sh9_basis_polynomials,
    sh9_from_cube, shadow_mask, CubeLevel, Environment, EstimateOptions, LightKind, Sh9,
    ShadowMethod, ShadowOptions, CUBE_FACES,
};
use parallax::reference::{self, Images, LightRecord, RenderOptions, SampleBudget};
use parallax::{Error, Result};

use crate::common::CommonArgs;

/// Arguments of `parallax eval lights`.
#[derive(clap::Args, Debug)]
pub struct LightsArgs {
    /// Built-in scene to evaluate (repeatable).
    #[arg(long = "scene", value_name = "NAME", default_values = ["room", "two-lights", "window"])]
    scenes: Vec<String>,
    /// Rendered image width, pixels.
    #[arg(long, default_value_t = 320)]
    width: u32,
    /// Rendered image height, pixels.
    #[arg(long, default_value_t = 240)]
    height: u32,
    /// Path-tracing samples per pixel.
    #[arg(long, default_value_t = 32)]
    spp: u32,
    /// Depth from stereo matching of the rendered pair instead of the renderer's exact depth and
    /// normals.
    #[arg(long)]
    stereo: bool,
    /// Also decompose the SH error (per band, seen/unseen directions, emitters, photo part and
    /// lights part) and write it to `decomposition.md`.
    #[arg(long)]
    decompose: bool,
    /// Where `lights.md` and `lights.json` go.
    #[arg(long, default_value = "target/eval-lights", value_name = "DIR")]
    out: PathBuf,
    #[command(flatten)]
    common: CommonArgs,
}

#[derive(serde::Serialize)]
struct Row {
    scene: String,
    variant: &'static str,
    true_lights: usize,
    true_in_view: usize,
    found_positional: usize,
    main_in_view: bool,
    main_error_deg: f32,
    position_error_pct: Option<f32>,
    fallback: bool,
    iou_thesis: f32,
    iou_chromaticity: f32,
    sh_rel_rms: f32,
    shading_rel_rms: f32,
    seconds: f64,
    /// The estimate's lights (left camera frame, metres), in-view sources first.
    estimated_lights: Vec<parallax::light::Light>,
}

/// Irradiance (luminance) a true light gives a surface facing it at `p`, and the unit direction
/// from `p` towards it.
fn true_light_at(l: &LightRecord, p: Vec3) -> (f32, Vec3) {
    let lum = |c: [f32; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
    if let (Some(d), Some(e)) = (l.direction, l.irradiance) {
        return (lum(e), -Vec3::from(d).normalize());
    }
    let pos = Vec3::from(l.position.unwrap_or([0.0; 3]));
    let to = pos - p;
    let r = to.length().max(1e-3);
    let facing = l
        .normal
        .map_or(1.0, |n| Vec3::from(n).dot(-to / r).max(0.0));
    (
        lum(l.intensity.unwrap_or([0.0; 3])) * facing / (r * r),
        to / r,
    )
}

fn in_view(camera: &Camera, p: Vec3) -> bool {
    camera.project_to_pixel(p).is_some()
}

fn iou(mask: &Raster<f32>, truth: &[bool], valid: &[bool]) -> f32 {
    let (mut i, mut u) = (0usize, 0usize);
    for ((m, t), v) in mask.pixels().iter().zip(truth).zip(valid) {
        if *v {
            let m = *m > 0.5;
            i += (m && *t) as usize;
            u += (m || *t) as usize;
        }
    }
    if u == 0 {
        1.0
    } else {
        i as f32 / u as f32
    }
}

/// Relative RMS of the diffuse radiance of two SH9 over the sphere (RGB, 2000 directions).
fn sh_error(estimate: &Sh9, truth: &Sh9) -> f32 {
    sh_distance(estimate, truth, truth)
}

/// RMS over the sphere of the diffuse radiance of `a − b`, relative to the RMS of `reference`
/// (RGB, 2000 directions).
fn sh_distance(a: &Sh9, b: &Sh9, reference: &Sh9) -> f32 {
    let (mut err, mut total) = (0.0f64, 0.0f64);
    let n = 2000;
    for i in 0..n {
        let z = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
        let r = (1.0 - z * z).sqrt();
        let phi = i as f32 * 2.399_963;
        let d = Vec3::new(r * phi.cos(), z, r * phi.sin());
        let p = sh9_basis_polynomials(d);
        for k in 0..3 {
            let e: f32 = a.coefficients.iter().zip(p).map(|(c, w)| c[k] * w).sum();
            let t: f32 = b.coefficients.iter().zip(p).map(|(c, w)| c[k] * w).sum();
            let r: f32 = reference
                .coefficients
                .iter()
                .zip(p)
                .map(|(c, w)| c[k] * w)
                .sum();
            err += ((e - t) as f64).powi(2);
            total += (r as f64).powi(2);
        }
    }
    (err / total.max(1e-12)).sqrt() as f32
}

/// Radiance above which a probe texel is taken as looking at an emitter (the built-in scenes'
/// emitters are 16 and more; their lit surfaces and the window's sky stay below 4).
const EMITTER_RADIANCE: f32 = 5.0;

/// `level` averaged (by solid angle of its texels, via their centres) into a cube of `n`.
fn resample(level: &CubeLevel, n: usize) -> CubeLevel {
    let m = level.size as usize;
    let mut sum = vec![[0.0f64; 3]; CUBE_FACES * n * n];
    let mut count = vec![0.0f64; CUBE_FACES * n * n];
    for f in 0..CUBE_FACES {
        for j in 0..m {
            for i in 0..m {
                let (s, t) = ((i as f32 + 0.5) / m as f32, (j as f32 + 0.5) / m as f32);
                let d = cube_direction(f, s, t);
                // Solid angle of a texel ∝ 1 / (1 + sc² + tc²)^1.5.
                let (sc, tc) = (2.0 * s - 1.0, 2.0 * t - 1.0);
                let w = (1.0 + sc * sc + tc * tc).powf(-1.5) as f64;
                let (g, s2, t2) = cube_texel(d);
                let idx = g * n * n
                    + ((t2 * n as f32) as usize).min(n - 1) * n
                    + ((s2 * n as f32) as usize).min(n - 1);
                let c = level.texels[f * m * m + j * m + i];
                for k in 0..3 {
                    sum[idx][k] += c[k] as f64 * w;
                }
                count[idx] += w;
            }
        }
    }
    CubeLevel {
        size: n as u32,
        texels: sum
            .iter()
            .zip(&count)
            .map(|(s, c)| s.map(|v| if *c > 0.0 { (v / c) as f32 } else { 0.0 }))
            .collect(),
    }
}

/// SH9 of the texels of `level` where `keep` holds (the others black).
fn sh_where(level: &CubeLevel, keep: impl Fn(usize, [f32; 3]) -> bool) -> Sh9 {
    let texels = level
        .texels
        .iter()
        .enumerate()
        .map(|(i, c)| if keep(i, *c) { *c } else { [0.0; 3] })
        .collect();
    sh9_from_cube(
        &CubeLevel {
            size: level.size,
            texels,
        },
        f32::MAX,
        0.0,
    )
}

/// `sh` with coefficient group `from..to` replaced by `other`'s.
fn with_bands(sh: &Sh9, other: &Sh9, from: usize, to: usize) -> Sh9 {
    let mut out = *sh;
    out.coefficients[from..to].copy_from_slice(&other.coefficients[from..to]);
    out
}

/// Which texels of a cube of `n` some photo pixel with depth is seen in from `point`.
fn seen_texels(depth: &Raster<f32>, camera: &Camera, point: Vec3, n: usize) -> Vec<bool> {
    let mut seen = vec![false; CUBE_FACES * n * n];
    for y in 0..depth.height() {
        for x in 0..depth.width() {
            let (u, v) = (x as f32 + 0.5, y as f32 + 0.5);
            let dir = match camera.unproject(u, v, *depth.get(x, y)) {
                Some(q) => q - point,
                None => camera.ray_direction(u, v),
            };
            if dir.length() > 0.0 {
                let (f, s, t) = cube_texel(dir);
                seen[f * n * n
                    + ((t * n as f32) as usize).min(n - 1) * n
                    + ((s * n as f32) as usize).min(n - 1)] = true;
            }
        }
    }
    seen
}

/// One row of the SH error decomposition.
#[derive(serde::Serialize)]
struct Decomposition {
    scene: String,
    variant: &'static str,
    /// Relative RMS error, all bands (as the main table).
    total: f32,
    /// The part from the DC coefficient alone (bands 1–2 taken from the truth).
    dc: f32,
    /// The part from bands 1–2 alone.
    bands12: f32,
    /// Luminance of the estimate's DC over the truth's.
    dc_ratio: f32,
    /// Diffuse radiance (luminance) facing up: estimate, truth.
    up_estimate: f32,
    up_truth: f32,
    /// Fraction of the sphere (probe texels) seen through the photo.
    seen_fraction: f32,
    /// Error of the estimate restricted to the seen / the unseen directions, relative to the
    /// whole truth.
    seen_part: f32,
    unseen_part: f32,
    /// Share of the truth's SH (RMS) from emitter texels.
    truth_emitters: f32,
    /// The photo's environment without lights against the truth without emitters.
    photo_vs_rest: f32,
    /// The same from the unclipped (HDR) render instead of the LDR photo.
    hdr_photo_vs_rest: f32,
    /// The fitted lights alone against the truth's emitters (relative to the whole truth).
    lights_vs_emitters: f32,
    /// DC luminance: fitted lights alone, truth's emitters alone.
    lights_dc: f32,
    emitters_dc: f32,
    /// The total error with every coefficient reduced to its luminance (colour ignored).
    luminance_total: f32,
    /// The photo's environment without lights against the truth without emitters, restricted
    /// to the seen / unseen directions (relative to the whole truth).
    photo_seen: f32,
    photo_unseen: f32,
    /// Diffuse radiance facing up (luminance): the photo's environment without lights, the
    /// truth without emitters, and the fit's ambient.
    photo_up: f32,
    rest_up: f32,
    fit_ambient: f32,
}

#[allow(clippy::too_many_arguments)]
fn decompose(
    name: &str,
    variant: &'static str,
    probe: &CubeLevel,
    estimate: &light::LightingEstimate,
    photo: &Raster<[f32; 3]>,
    hdr: &Raster<[f32; 3]>,
    depth: &Raster<f32>,
    camera: &Camera,
    point: Vec3,
    up: Vec3,
) -> Result<Decomposition> {
    let options = light::EnvironmentOptions::default();
    let truth = sh9_from_cube(probe, f32::MAX, 0.0);
    let est = &estimate.environment.sh9;
    let n = probe.size as usize;
    let est_cube = resample(
        estimate
            .environment
            .cube
            .levels
            .first()
            .ok_or_else(|| Error::Internal("environment without a cube".into()))?,
        n,
    );
    let seen = seen_texels(depth, camera, point, n);
    let seen_fraction = {
        let (mut a, mut b) = (0.0f64, 0.0f64);
        for (i, s) in seen.iter().enumerate() {
            let (j, k) = ((i / n) % n, i % n);
            let (sc, tc) = (
                2.0 * (k as f32 + 0.5) / n as f32 - 1.0,
                2.0 * (j as f32 + 0.5) / n as f32 - 1.0,
            );
            let w = (1.0 + sc * sc + tc * tc).powf(-1.5) as f64;
            b += w;
            if *s {
                a += w;
            }
        }
        (a / b) as f32
    };
    let part = |keep: &dyn Fn(usize) -> bool| {
        sh_distance(
            &sh_where(&est_cube, |i, _| keep(i)),
            &sh_where(probe, |i, _| keep(i)),
            &truth,
        )
    };
    let is_emitter = |c: [f32; 3]| luminance(c) > EMITTER_RADIANCE;
    let truth_rest = sh_where(probe, |_, c| !is_emitter(c));
    let truth_emit = sh_where(probe, |_, c| is_emitter(c));
    let black = Raster::filled(photo.width(), photo.height(), [0.0f32; 3]);
    let photo_only =
        Environment::from_photo_with_up(photo, Some(depth), camera, point, up, &[], &options)?;
    let hdr_only =
        Environment::from_photo_with_up(hdr, Some(depth), camera, point, up, &[], &options)?;
    let lights_only = Environment::from_photo_with_up(
        &black,
        Some(depth),
        camera,
        point,
        up,
        &estimate.fit.lights,
        &options,
    )?;
    let zero = Sh9::default();
    let grey = |sh: &Sh9| Sh9 {
        coefficients: sh.coefficients.map(|c| [luminance(c); 3]),
    };
    let photo_cube = resample(
        photo_only
            .cube
            .levels
            .first()
            .ok_or_else(|| Error::Internal("environment without a cube".into()))?,
        n,
    );
    let photo_part = |keep: &dyn Fn(usize) -> bool| {
        sh_distance(
            &sh_where(&photo_cube, |i, _| keep(i)),
            &sh_where(probe, |i, c| keep(i) && !is_emitter(c)),
            &truth,
        )
    };
    let up_of = |sh: &Sh9| luminance(sh.diffuse_radiance(up));
    Ok(Decomposition {
        scene: name.to_string(),
        variant,
        total: sh_error(est, &truth),
        dc: sh_error(&with_bands(est, &truth, 1, 9), &truth),
        bands12: sh_error(&with_bands(est, &truth, 0, 1), &truth),
        dc_ratio: luminance(est.coefficients[0]) / luminance(truth.coefficients[0]).max(1e-9),
        up_estimate: up_of(est),
        up_truth: up_of(&truth),
        seen_fraction,
        seen_part: part(&|i| seen[i]),
        unseen_part: part(&|i| !seen[i]),
        truth_emitters: sh_distance(&truth_emit, &zero, &truth),
        photo_vs_rest: sh_distance(&photo_only.sh9, &truth_rest, &truth),
        hdr_photo_vs_rest: sh_distance(&hdr_only.sh9, &truth_rest, &truth),
        lights_vs_emitters: sh_distance(&lights_only.sh9, &truth_emit, &truth),
        lights_dc: luminance(lights_only.sh9.coefficients[0]),
        emitters_dc: luminance(truth_emit.coefficients[0]),
        luminance_total: sh_error(&grey(est), &grey(&truth)),
        photo_seen: photo_part(&|i| seen[i]),
        photo_unseen: photo_part(&|i| !seen[i]),
        photo_up: up_of(&photo_only.sh9),
        rest_up: up_of(&truth_rest),
        fit_ambient: luminance(estimate.fit.ambient),
    })
}

fn evaluate(
    name: &str,
    variant: &'static str,
    scene: &reference::Scene,
    args: &LightsArgs,
) -> Result<(Row, Option<Decomposition>)> {
    let options = RenderOptions {
        width: Some(args.width),
        height: Some(args.height),
        samples: SampleBudget::PerPixel(args.spp),
        ..Default::default()
    };
    let images: Images = reference::render(scene, &options)?;
    let (w, h) = (images.left.width(), images.left.height());
    let c = &images.calibration;
    let camera = Camera::new(
        c.focal_px as f32,
        c.focal_px as f32,
        c.cx as f32,
        c.cy as f32,
        w as u32,
        h as u32,
    )?;
    // Insertion point: in front of the table's centre, 2 cm above its top (world → camera).
    let table_x = if name == "window" { 0.2 } else { 0.0 };
    let to_camera = Mat4::from_cols_array(&images.camera_to_world).inverse();
    let point = to_camera.transform_point3(Vec3::new(table_x, 0.77, -1.6));
    let photo = images.left.map(|c| c.map(|v| v.clamp(0.0, 1.0)));
    let start = Instant::now();
    let (depth, estimate) = if args.stereo {
        // What a host gets: the whole Scene on the 8-bit pair (its search range from the
        // calibration, its own up, normals snapped to its planes), around the same point.
        let pair = |r: &Raster<[f32; 3]>| {
            parallax::image::Image::from_linear_rgb(&r.map(|c| c.map(|v| v.clamp(0.0, 1.0))))
        };
        let (l, r) = (pair(&images.left), pair(&images.right));
        let context = parallax::context::Context::new(Default::default())?;
        let mut scene = parallax::scene::Scene::new(std::sync::Arc::new(context));
        scene.set_stereo_pair(&l.view(), &r.view())?;
        scene.set_calibration(*c)?;
        scene.set_insertion_point(point.to_array())?;
        let estimate = scene.lighting_estimate()?;
        ((*scene.depth()?).clone(), (*estimate).clone())
    } else {
        let estimate = estimate_lighting(
            &photo,
            &images.depth,
            Some(&images.normals),
            &camera,
            to_camera.transform_vector3(Vec3::Y).normalize().to_array(),
            Some(point.to_array()),
            &EstimateOptions::default(),
        )?;
        (images.depth.clone(), estimate)
    };
    let seconds = start.elapsed().as_secs_f64();
    if std::env::var("PLX_EVAL_DEBUG").is_ok() {
        eprintln!(
            "{:?}\nup {:?} point {point}",
            estimate.fit,
            to_camera.transform_vector3(Vec3::Y)
        );
    }
    let thesis = shadow_mask(
        &photo,
        None,
        &ShadowOptions {
            method: ShadowMethod::Thesis,
            ..Default::default()
        },
    )?;
    let valid: Vec<bool> = images
        .depth
        .pixels()
        .iter()
        .map(|z| z.is_finite())
        .collect();
    let truth_shadow: Vec<bool> = (0..w * h)
        .map(|i| {
            let mean: f32 = images.shadow.iter().map(|s| s.pixels()[i]).sum::<f32>()
                / images.shadow.len() as f32;
            mean < 0.5
        })
        .collect();
    let iou_thesis = iou(&thesis, &truth_shadow, &valid);
    let iou_chromaticity = iou(&estimate.shadow_mask, &truth_shadow, &valid);

    // The true main light: most irradiance at the insertion point.
    let main_truth = images
        .lights
        .iter()
        .map(|l| (l, true_light_at(l, point)))
        .max_by(|a, b| a.1 .0.total_cmp(&b.1 .0))
        .ok_or_else(|| Error::invalid(format!("scene {name} has no light")))?;
    let main_in_view = main_truth
        .0
        .position
        .is_some_and(|p| in_view(&camera, Vec3::from(p)));
    let (towards, _) = estimate.fit.main.towards(point);
    let main_error_deg = towards.angle_between(main_truth.1 .1).to_degrees();
    let positional: Vec<Vec3> = estimate
        .fit
        .lights
        .iter()
        .filter(|l| l.kind != LightKind::Directional)
        .map(|l| Vec3::from(l.position))
        .collect();
    let visible: Vec<Vec3> = images
        .lights
        .iter()
        .filter_map(|l| l.position.map(Vec3::from))
        .filter(|p| in_view(&camera, *p))
        .collect();
    let position_error_pct = (!visible.is_empty() && !positional.is_empty()).then(|| {
        let errors: Vec<f32> = visible
            .iter()
            .map(|t| {
                positional
                    .iter()
                    .map(|e| e.distance(*t))
                    .fold(f32::MAX, f32::min)
                    / t.length()
                    * 100.0
            })
            .collect();
        errors.iter().sum::<f32>() / errors.len() as f32
    });
    let probe = reference::radiance_probe(
        scene,
        &RenderOptions {
            samples: SampleBudget::PerPixel(64),
            ..options
        },
        point.to_array(),
        24,
    )?;
    let truth_sh = sh9_from_cube(&probe, f32::MAX, 0.0);
    let sh_rel_rms = sh_error(&estimate.environment.sh9, &truth_sh);
    let decomposition = if args.decompose {
        Some(decompose(
            name,
            variant,
            &probe,
            &estimate,
            &photo,
            &images.left,
            &depth,
            &camera,
            point,
            to_camera.transform_vector3(Vec3::Y).normalize(),
        )?)
    } else {
        None
    };
    if !args.common.quiet {
        eprintln!(
            "{name} ({variant}): main {:?} dir {:.1}°, lights {} found / {} true, IoU {:.2}/{:.2}, SH {:.1} %, shading {:.1} %, fallback {}",
            estimate.fit.main.kind,
            main_error_deg,
            positional.len(),
            images.lights.len(),
            iou_thesis,
            iou_chromaticity,
            sh_rel_rms * 100.0,
            estimate.fit.residual * 100.0,
            estimate.fit.fallback_used
        );
    }
    let row = Row {
        scene: name.to_string(),
        variant,
        true_lights: images.lights.len(),
        true_in_view: visible.len(),
        found_positional: positional.len(),
        main_in_view,
        main_error_deg,
        position_error_pct,
        fallback: estimate.fit.fallback_used,
        iou_thesis,
        iou_chromaticity,
        sh_rel_rms,
        shading_rel_rms: estimate.fit.residual,
        seconds,
        estimated_lights: estimate.fit.lights.clone(),
    };
    Ok((row, decomposition))
}

/// Runs the evaluation and writes the table.
pub fn run(args: LightsArgs) -> Result<()> {
    std::fs::create_dir_all(&args.out).map_err(|e| Error::io(&args.out, e))?;
    let mut rows = Vec::new();
    let mut parts = Vec::new();
    for name in &args.scenes {
        let scene = reference::builtin(name)?;
        let (row, part) = evaluate(name, "as built", &scene, &args)?;
        rows.push(row);
        parts.extend(part);
        // The same room with the camera tilted down 0.8 m at the look-at point, so lights high
        // in the room leave the frame.
        let mut tilted = scene.clone();
        tilted.camera.look_at[1] -= 0.8;
        let (row, part) = evaluate(name, "tilted down", &tilted, &args)?;
        rows.push(row);
        parts.extend(part);
    }
    let mut md = String::new();
    let _ = writeln!(
        md,
        "# Illumination estimate against synthetic truth\n\n`parallax eval lights --width {} --height {} --spp {}{}` \
         (depth and normals: {}; the photo is the left view clipped to [0, 1]).\n",
        args.width,
        args.height,
        args.spp,
        if args.stereo { " --stereo" } else { "" },
        if args.stereo { "the Scene's, from the 8-bit pair" } else { "the renderer's exact ones" }
    );
    let _ = writeln!(
        md,
        "| scene | camera | lights (in view) | found | main light in view | main dir. error | in-view position error | fallback | shadow IoU thesis | shadow IoU chromaticity | SH irradiance rel. RMS | shading rel. RMS | time |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    );
    for r in &rows {
        let _ = writeln!(
            md,
            "| {} | {} | {} ({}) | {} | {} | {:.1}° | {} | {} | {:.2} | {:.2} | {:.1} % | {:.1} % | {:.2} s |",
            r.scene,
            r.variant,
            r.true_lights,
            r.true_in_view,
            r.found_positional,
            if r.main_in_view { "yes" } else { "no" },
            r.main_error_deg,
            r.position_error_pct.map_or("–".to_string(), |v| format!("{v:.1} %")),
            if r.fallback { "yes" } else { "no" },
            r.iou_thesis,
            r.iou_chromaticity,
            r.sh_rel_rms * 100.0,
            r.shading_rel_rms * 100.0,
            r.seconds
        );
    }
    let _ = writeln!(
        md,
        "\nDefinitions: *main dir. error* — angle at the insertion point (2 cm above the table, in front of its centre) \
         between the direction to the estimated main light and to the true light giving the most irradiance there; \
         *in-view position error* — distance from each true light inside the frame to the nearest estimated positional \
         light, as % of the true light's distance from the camera; *found* — positional lights kept by the fit (in-view sources and fitted out-of-view point lights); \
         *shadow IoU* — against the pixels where the true visibility averaged over the lights is below 0.5 \
         (surfaces facing away count as shadow), mask > 0.5; *SH irradiance rel. RMS* — over 2000 directions, RGB, the estimate's SH9 \
         against the SH9 of a path-traced radiance probe at the insertion point (24² per face, 64 paths per texel); \
         *shading rel. RMS* — the fitted model (one albedo per continuous region) against the photo's luminance on \
         the fit's samples; *time* — the estimate (mask, sources, fit, environment) on this machine. \
         `lights.json` also lists each row's estimated lights (`estimated_lights`, left camera frame, metres)."
    );
    let path = args.out.join("lights.md");
    std::fs::write(&path, &md).map_err(|e| Error::io(&path, e))?;
    let path = args.out.join("lights.json");
    let json = serde_json::to_string_pretty(&rows)
        .map_err(|e| Error::Internal(format!("lights JSON: {e}")))?;
    std::fs::write(&path, json).map_err(|e| Error::io(&path, e))?;
    print!("{md}");
    if args.decompose {
        write_decomposition(&args, &parts)?;
    }
    Ok(())
}

fn write_decomposition(args: &LightsArgs, parts: &[Decomposition]) -> Result<()> {
    let mut md = String::new();
    let _ = writeln!(
        md,
        "# SH irradiance error, decomposed\n\n`parallax eval lights --decompose{}`. Errors are RMS over the sphere of \
         the diffuse radiance, relative to the truth's RMS (so parts compare with the total).\n",
        if args.stereo { " --stereo" } else { "" }
    );
    let _ = writeln!(
        md,
        "| scene | camera | total | DC only | bands 1–2 only | DC est./truth | up est. | up truth | seen | seen-dir. part | unseen-dir. part | truth emitters | photo env vs truth w/o emitters | same, HDR render | lights vs emitters | lights DC | emitters DC | total, luminance only | photo env, seen part | photo env, unseen part | photo env up | truth w/o emitters up | fit ambient |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    );
    let pct = |v: f32| format!("{:.1} %", v * 100.0);
    for d in parts {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {:.2} | {:.3} | {:.3} | {} | {} | {} | {} | {} | {} | {} | {:.3} | {:.3} | {} | {} | {} | {:.3} | {:.3} | {:.3} |",
            d.scene,
            d.variant,
            pct(d.total),
            pct(d.dc),
            pct(d.bands12),
            d.dc_ratio,
            d.up_estimate,
            d.up_truth,
            pct(d.seen_fraction),
            pct(d.seen_part),
            pct(d.unseen_part),
            pct(d.truth_emitters),
            pct(d.photo_vs_rest),
            pct(d.hdr_photo_vs_rest),
            pct(d.lights_vs_emitters),
            d.lights_dc,
            d.emitters_dc,
            pct(d.luminance_total),
            pct(d.photo_seen),
            pct(d.photo_unseen),
            d.photo_up,
            d.rest_up,
            d.fit_ambient
        );
    }
    let path = args.out.join("decomposition.md");
    std::fs::write(&path, &md).map_err(|e| Error::io(&path, e))?;
    let path = args.out.join("decomposition.json");
    let json = serde_json::to_string_pretty(parts)
        .map_err(|e| Error::Internal(format!("decomposition JSON: {e}")))?;
    std::fs::write(&path, json).map_err(|e| Error::io(&path, e))?;
    eprint!("{md}");
    Ok(())
}
