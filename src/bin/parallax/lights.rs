//! `parallax lights`: the illumination estimate of a stereo pair (or depth + photo): shadow mask,
//! light sources in view, the fitted main light and ambient, SH9 and the environment, as JSON, a
//! preview over the photo, and the environment as an equirectangular EXR.

use std::path::PathBuf;

use glam::Vec3;
use parallax::image::{Image, Raster};
use parallax::light::{prefilter::sample_cube, Environment, EnvironmentOptions, Light, LightKind};
use parallax::mesh::UpSource;
use parallax::trace::Trace;
use parallax::{Error, Result};

use crate::common::CommonArgs;
use crate::depth_input::{absorb, DepthInput};
use crate::previews::lights_preview;

/// Arguments of `parallax lights`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    input: DepthInput,
    /// Folder of equirectangular HDR/EXR maps: the one whose SH irradiance (normalised, best yaw)
    /// is nearest to the estimate's becomes the environment, rotated to that yaw.
    #[arg(long, value_name = "DIR")]
    env_library: Option<PathBuf>,
    /// Write the lights, ambient and SH9 as JSON.
    #[arg(long, value_name = "FILE.json")]
    out: Option<PathBuf>,
    /// Draw the shadow mask, the light blobs and the main light's direction over the photo (PNG).
    #[arg(long, value_name = "FILE.png")]
    out_preview: Option<PathBuf>,
    /// Write the environment as an equirectangular OpenEXR (256×128).
    #[arg(long, value_name = "FILE.exr")]
    out_env: Option<PathBuf>,
    /// Where objects will go, `X,Y,Z` in the left camera's frame (metres, +Y up, −Z forward): the
    /// environment and SH9 are built around it. Default: the median point of the up-facing
    /// surfaces, 2 cm above them.
    #[arg(long, value_name = "X,Y,Z", value_parser = crate::common::parse_vec3, allow_hyphen_values = true)]
    insertion_point: Option<[f32; 3]>,
    #[command(flatten)]
    common: CommonArgs,
}

#[derive(serde::Serialize)]
struct Output<'a> {
    frame: &'static str,
    main: &'a Light,
    ambient: [f32; 3],
    lights: &'a [Light],
    sources_detected: &'a [Light],
    fallback_used: bool,
    residual: f32,
    insertion_point: [f32; 3],
    sh9: [f32; 27],
    sh9_convention: &'static str,
    environment_seen_fraction: f32,
    environment_source: String,
}

/// Equirect (the reference's layout) of a cube's first level.
fn to_equirect(env: &Environment, w: usize, h: usize) -> Raster<[f32; 3]> {
    let level = &env.cube.levels[0];
    Raster::from_fn(w, h, |x, y| {
        let d = parallax::light::environment::equirect_direction(
            (x as f32 + 0.5) / w as f32,
            (y as f32 + 0.5) / h as f32,
        );
        sample_cube(level, d)
    })
}

/// Nearest library map: compares SH9 irradiance normalised by its mean over 36 yaws.
fn library_match(
    dir: &PathBuf,
    estimate: &Environment,
    trace: &mut Trace,
) -> Result<Option<(String, Environment)>> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    let limits = parallax::image::ImageLimits::default();
    let options = EnvironmentOptions {
        face_size: 32,
        ..Default::default()
    };
    let directions: Vec<Vec3> = (0..200)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f32 + 0.5) / 200.0;
            let r = (1.0 - z * z).sqrt();
            let phi = i as f32 * 2.399_963;
            Vec3::new(r * phi.cos(), z, r * phi.sin())
        })
        .collect();
    let profile = |env: &Environment, yaw: f32| -> Vec<f32> {
        let (s, c) = yaw.sin_cos();
        let v: Vec<f32> = directions
            .iter()
            .map(|d| {
                let r = Vec3::new(c * d.x + s * d.z, d.y, -s * d.x + c * d.z);
                parallax::light::luminance(env.sh9.diffuse_radiance(r))
            })
            .collect();
        let mean = v.iter().sum::<f32>() / v.len() as f32;
        v.iter().map(|x| x / mean.max(1e-9)).collect()
    };
    let target = profile(estimate, 0.0);
    let mut best: Option<(f32, String, Raster<[f32; 3]>, f32)> = None;
    for entry in entries.flatten() {
        let path = entry.path();
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        let map = match ext.as_str() {
            "hdr" => Raster::read_hdr(&path, &limits),
            "exr" => Image::load(&path, &limits).map(|i| i.to_linear_rgb()),
            _ => continue,
        };
        let map = match map {
            Ok(m) => m,
            Err(e) => {
                trace.warn(format!(
                    "environment library: skipped {}: {e}",
                    path.display()
                ));
                continue;
            }
        };
        let env = Environment::from_equirect(&map, &options)?;
        for k in 0..36 {
            let yaw = k as f32 * std::f32::consts::TAU / 36.0;
            let p = profile(&env, yaw);
            let d: f32 = p.iter().zip(&target).map(|(a, b)| (a - b).powi(2)).sum();
            if best.as_ref().is_none_or(|b| d < b.0) {
                best = Some((d, path.display().to_string(), map.clone(), yaw));
            }
        }
    }
    let Some((_, name, map, yaw)) = best else {
        return Ok(None);
    };
    // Rotate the map by the yaw (columns shift), and scale it to the estimate's mean irradiance.
    let w = map.width();
    let shift = ((yaw / std::f32::consts::TAU) * w as f32).round() as usize % w.max(1);
    let rotated = Raster::from_fn(w, map.height(), |x, y| *map.get((x + shift) % w, y));
    let env = Environment::from_equirect(&rotated, &EnvironmentOptions::default())?;
    let mean = |e: &Environment| {
        directions
            .iter()
            .map(|d| parallax::light::luminance(e.sh9.diffuse_radiance(*d)))
            .sum::<f32>()
    };
    let scale = mean(estimate) / mean(&env).max(1e-9);
    let scaled = rotated.map(|c| c.map(|v| v * scale));
    Ok(Some((
        name,
        Environment::from_equirect(&scaled, &EnvironmentOptions::default())?,
    )))
}

/// Estimates the lighting and writes what was asked for.
pub fn run(args: Args) -> Result<()> {
    if args.out.is_none() && args.out_preview.is_none() && args.out_env.is_none() {
        return Err(Error::invalid(
            "give --out FILE.json, --out-preview FILE.png and/or --out-env FILE.exr",
        ));
    }
    let mut trace = Trace::new();
    let loaded = args.input.load(&mut trace)?;
    let mut scene = loaded.scene;
    let photo = loaded
        .photo
        .ok_or_else(|| {
            Error::invalid("parallax lights needs the photo: --left/--right or --image")
        })?
        .to_linear_rgb();
    let spinner = args.common.spinner("estimating the lighting");
    if let Some(point) = args.insertion_point {
        scene.set_insertion_point(point)?;
    }
    // The Scene's estimate, as a host gets it: normals snapped to the support planes, the
    // matcher's confidence in the planes.
    let estimate = scene.lighting_estimate();
    absorb(&mut trace, &scene);
    let estimate = args.common.or_warnings(&trace, estimate)?;
    let camera = scene.camera();
    absorb(&mut trace, &scene);
    let camera = args.common.or_warnings(&trace, camera)?;
    let surfaces = scene.surfaces();
    absorb(&mut trace, &scene);
    let surfaces = args.common.or_warnings(&trace, surfaces)?;
    spinner.finish_and_clear();
    if surfaces.up_source == UpSource::CameraFallback {
        trace.warn("no near-horizontal plane found: up is the camera's +Y");
    }
    let mut environment = estimate.environment.clone();
    let mut environment_source = "photo".to_string();
    if let Some(dir) = &args.env_library {
        if let Some((name, env)) = library_match(dir, &environment, &mut trace)? {
            environment = env;
            environment_source = name;
        } else {
            trace.warn(format!("no HDR/EXR map in {}", dir.display()));
        }
    }
    if let Some(path) = &args.out {
        let out = Output {
            frame: "left camera: x right, y up, z backwards, metres",
            main: &estimate.fit.main,
            ambient: estimate.fit.ambient,
            lights: &estimate.fit.lights,
            sources_detected: &estimate.sources,
            fallback_used: estimate.fit.fallback_used,
            residual: estimate.fit.residual,
            insertion_point: estimate.insertion_point,
            sh9: environment.sh9.to_array(),
            sh9_convention: "Filament pre-scaled irradiance, ARCore order: diffuse radiance of a white \
                             Lambertian surface with normal n = sum_i c_i * P_i(n), P = 1, y, z, x, xy, yz, 3z^2-1, xz, x^2-y^2",
            environment_seen_fraction: estimate.environment.seen_fraction,
            environment_source,
        };
        let json = serde_json::to_string_pretty(&out)
            .map_err(|e| Error::Internal(format!("lights JSON: {e}")))?;
        std::fs::write(path, json).map_err(|e| Error::io(path, e))?;
    }
    if let Some(path) = &args.out_env {
        to_equirect(&environment, 256, 128).write_exr(path)?;
    }
    if let Some(path) = &args.out_preview {
        let out = lights_preview(&photo, &estimate, &camera);
        Image::from_linear_rgb(&out).save_png(path)?;
    }
    if !args.common.quiet {
        let m = &estimate.fit.main;
        // A directional light's `direction` is where its light travels; a point or area light is
        // better told by where it is. Both by the direction towards it from where objects go.
        let place = match m.kind {
            LightKind::Directional => String::new(),
            _ => format!(
                " at ({:.2}, {:.2}, {:.2}) m",
                m.position[0], m.position[1], m.position[2]
            ),
        };
        let size = match m.kind {
            LightKind::Directional => format!("{:.1}°", m.size),
            _ => format!("{:.2} m", m.size),
        };
        let (towards, _) = m.towards(Vec3::from(estimate.insertion_point));
        eprintln!(
            "main light: {:?}{place}, towards it from the insertion point ({:.2}, {:.2}, {:.2}), size {size}, intensity ({:.3}, {:.3}, {:.3}){}",
            m.kind,
            towards.x,
            towards.y,
            towards.z,
            m.intensity[0],
            m.intensity[1],
            m.intensity[2],
            if estimate.fit.fallback_used { " [fallback]" } else { "" }
        );
        eprintln!(
            "{} light(s) in view, ambient ({:.3}, {:.3}, {:.3}), residual {:.1} %",
            estimate.sources.len(),
            estimate.fit.ambient[0],
            estimate.fit.ambient[1],
            estimate.fit.ambient[2],
            estimate.fit.residual * 100.0
        );
    }
    args.common.finish(&trace)
}
