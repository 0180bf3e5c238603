//! `parallax surfaces`: support planes and the gravity "up", as JSON and as a preview over the
//! photo, through the Scene (the report shows stereo, depth, mesh.grid, surfaces).

use std::path::PathBuf;

use parallax::image::Image;
use parallax::mesh::{MeshOptions, SurfaceOptions};
use parallax::trace::Trace;
use parallax::{Error, Result};

use crate::common::CommonArgs;
use crate::depth_input::{absorb, DepthInput};
use crate::previews::{grey_depth, surfaces_preview};

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
    let depth = args.common.or_warnings(&trace, depth)?;
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
    let found = args.common.or_warnings(&trace, found)?;
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
        let camera = args.common.or_warnings(&trace, camera)?;
        let background = match &loaded_photo {
            Some(photo) => photo.to_linear_rgb(),
            None => grey_depth(&depth),
        };
        let out = surfaces_preview(&background, &depth, &camera, &found);
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
