//! `parallax surfaces`: support planes and the gravity "up", as JSON and as a preview over the
//! photo, through the Scene (the report shows stereo, depth, mesh.grid, surfaces).

use std::path::PathBuf;

use glam::Vec2;
use parallax::image::{Image, Raster};
use parallax::mesh::{MeshOptions, SurfaceOptions};
use parallax::trace::Trace;
use parallax::{Error, Result};

use crate::common::CommonArgs;
use crate::depth_input::{absorb, DepthInput};

/// Arguments of `parallax surfaces`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    input: DepthInput,
    /// Write the surfaces and the up vector as JSON.
    #[arg(long, value_name = "FILE.json")]
    out: Option<PathBuf>,
    /// Draw the surfaces over the photo (--image; a grey depth rendering without it) as PNG.
    #[arg(long, value_name = "FILE.png")]
    out_preview: Option<PathBuf>,
    /// At most this many surfaces.
    #[arg(long, default_value_t = 8)]
    max_surfaces: usize,
    #[command(flatten)]
    common: CommonArgs,
}

/// Tints, one per surface (cycled).
const COLOURS: [[f32; 3]; 8] = [
    [0.9, 0.2, 0.2],
    [0.2, 0.8, 0.2],
    [0.2, 0.4, 1.0],
    [1.0, 0.8, 0.1],
    [0.8, 0.2, 0.9],
    [0.1, 0.9, 0.9],
    [1.0, 0.5, 0.1],
    [0.6, 0.6, 0.6],
];

/// Finds the surfaces and writes what was asked for.
pub fn run(args: Args) -> Result<()> {
    if args.out.is_none() && args.out_preview.is_none() {
        return Err(Error::invalid(
            "give --out FILE.json and/or --out-preview FILE.png",
        ));
    }
    let mut trace = Trace::new();
    let loaded = args.input.load(&mut trace)?;
    let mut scene = loaded.scene;
    let loaded_photo = loaded.photo;
    let spinner = args.common.spinner("finding support surfaces");
    let depth = scene.depth();
    absorb(&mut trace, &scene);
    let depth = depth?;
    // Surfaces want every pixel's point; a step keeps large photos near 0.3 MP.
    let pixels = depth.len() as f64;
    let step = (pixels / 300_000.0).sqrt().ceil().max(1.0) as u32;
    scene.set_mesh_options(MeshOptions {
        step,
        ..Default::default()
    })?;
    scene.set_surface_options(SurfaceOptions {
        max_surfaces: args.max_surfaces,
        ..Default::default()
    })?;
    let found = scene.surfaces();
    absorb(&mut trace, &scene);
    let found = found?;
    spinner.finish_and_clear();
    if found.up_source == parallax::mesh::UpSource::CameraFallback {
        trace.warn("no near-horizontal plane found: up is the camera's +Y");
    }
    if let Some(path) = &args.out {
        let json = serde_json::to_string_pretty(&*found)
            .map_err(|e| Error::Internal(format!("surfaces JSON: {e}")))?;
        std::fs::write(path, json).map_err(|e| Error::io(path, e))?;
    }
    if let Some(path) = &args.out_preview {
        let camera = scene.camera();
        absorb(&mut trace, &scene);
        let camera = camera?;
        let background = match &loaded_photo {
            Some(photo) => photo.to_linear_rgb(),
            None => grey_depth(&depth),
        };
        let mut out = background.clone();
        let tolerance = SurfaceOptions::default().distance_tolerance * 2.0;
        for y in 0..out.height() {
            for x in 0..out.width() {
                let pixel = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let Some(p) = camera.unproject(pixel.x, pixel.y, *depth.get(x, y)) else {
                    continue;
                };
                // The first (largest) surface whose plane holds this pixel's point, inside its
                // extent.
                if let Some((i, _)) = found.surfaces.iter().enumerate().find(|(_, s)| {
                    s.distance(p).abs() <= tolerance * -p.z && s.contains_pixel(pixel)
                }) {
                    let c = COLOURS[i % COLOURS.len()];
                    let px = out.get_mut(x, y);
                    for k in 0..3 {
                        px[k] = 0.45 * px[k] + 0.55 * c[k];
                    }
                }
            }
        }
        for (i, s) in found.surfaces.iter().enumerate() {
            draw_polygon(&mut out, &s.polygon_image, COLOURS[i % COLOURS.len()]);
        }
        Image::from_linear_rgb(&out).save_png(path)?;
    }
    if !args.common.quiet {
        for (i, s) in found.surfaces.iter().enumerate() {
            eprintln!(
                "surface {i}: {:?}, normal ({:.3}, {:.3}, {:.3}), {} points, {:.2} m², rms {:.4} m",
                s.kind, s.normal.x, s.normal.y, s.normal.z, s.inliers, s.area_m2, s.rms_m
            );
        }
        eprintln!(
            "up ({:.3}, {:.3}, {:.3}) from {:?}",
            found.up.x, found.up.y, found.up.z, found.up_source
        );
    }
    args.common.finish(&trace)
}

/// Depth as grey (near bright), for previews without a photo.
fn grey_depth(depth: &Raster<f32>) -> Raster<[f32; 3]> {
    let (lo, hi) = parallax::camera::valid_depth_range(depth).unwrap_or((1.0, 2.0));
    depth.map(|&z| {
        if z.is_finite() && z > 0.0 {
            let t = if hi > lo { (hi - z) / (hi - lo) } else { 1.0 };
            let g = 0.05 + 0.6 * t * t;
            [g; 3]
        } else {
            [0.0; 3]
        }
    })
}

/// Outline of a polygon, two pixels wide.
fn draw_polygon(out: &mut Raster<[f32; 3]>, poly: &[Vec2], colour: [f32; 3]) {
    let (w, h) = (out.width() as i64, out.height() as i64);
    for (i, a) in poly.iter().enumerate() {
        let b = poly[(i + 1) % poly.len()];
        let steps = (b - *a).length().ceil().clamp(1.0, 100_000.0) as usize;
        for s in 0..=steps {
            let p = a.lerp(b, s as f32 / steps as f32);
            for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                let (x, y) = (p.x as i64 + dx, p.y as i64 + dy);
                if (0..w).contains(&x) && (0..h).contains(&y) {
                    *out.get_mut(x as usize, y as usize) = colour;
                }
            }
        }
    }
}
