//! `parallax demo`: the whole pipeline on the embedded default, with nothing to download.
//!
//! The reference path tracer renders the built-in `room` as a stereo pair (with exact ground
//! truth, written to `DIR/pair/`); then, as a host would: the pair and its calibration go into a
//! [`Scene`], a polished gold sphere (glossy) is stood on the table and a diffuse blue box on the
//! floor beside the table's right legs (the front leg hides part of it), each at a pixel, and the
//! composite is rendered with the estimated depth, mesh and lights.
//! Writes `DIR/composite.png`, every intermediate product (`composite --debug-dir`) and
//! `DIR/report.json`, the trace of every stage.

use std::path::PathBuf;
use std::sync::Arc;

use glam::{Mat4, Vec2, Vec3};
use parallax::artefact::builtin_glb;
use parallax::camera::Camera;
use parallax::context::{Context, ContextOptions};
use parallax::image::Image;
use parallax::mesh::{Orientation, PlaceOptions};
use parallax::reference::{self, SampleBudget};
use parallax::render::RenderOptions;
use parallax::scene::Scene;
use parallax::trace::Trace;
use parallax::{Error, Result};

use crate::common::CommonArgs;
use crate::composite::write_debug_dir;
use crate::depth_input::absorb;

/// Arguments of `parallax demo`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Where the images and the report go (created if missing).
    #[arg(long, default_value = "parallax-demo", value_name = "DIR")]
    out_dir: PathBuf,
    /// Width of the synthetic photo, pixels (the height keeps 4:3).
    #[arg(long, default_value_t = 480)]
    width: u32,
    /// Path-tracing samples per pixel of the synthetic pair (low: a few seconds).
    #[arg(long, default_value_t = 16)]
    spp: u32,
    #[command(flatten)]
    common: CommonArgs,
}

/// Where the glossy sphere stands on the table and the box on the floor, world metres (the room's
/// table spans x ∈ [−0.6, 0.6], z ∈ [−2.15, −1.45], top at y = 0.75; its legs stand 5 cm in
/// from the corners): the box beside the table's right legs, the back one partly in front of it.
const SPHERE_ON_TABLE: [f32; 3] = [0.2, 0.75, -1.6];
const BOX_BESIDE_TABLE: [f32; 3] = [0.72, 0.0, -1.95];
/// Largest side of each artefact, metres; the box's turn about up, degrees.
const SPHERE_SIZE_M: f32 = 0.2;
const BOX_SIZE_M: f32 = 0.25;
const BOX_YAW_DEG: f32 = 25.0;

/// Renders the demo and writes its outputs.
pub fn run(args: Args) -> Result<()> {
    if args.width < 64 || args.spp == 0 {
        return Err(Error::invalid(format!(
            "--width {} --spp {}: the demo needs a width of at least 64 and one sample",
            args.width, args.spp
        )));
    }
    let mut trace = Trace::new();
    let spinner = args
        .common
        .spinner("path tracing the synthetic room (stereo pair with ground truth)");
    let room = reference::builtin("room")?;
    let images = trace.time("demo.synth", "the room's stereo pair, path traced", |_| {
        reference::render(
            &room,
            &reference::RenderOptions {
                width: Some(args.width),
                samples: SampleBudget::PerPixel(args.spp),
                ..Default::default()
            },
        )
    })?;
    images.write_middlebury_layout(args.out_dir.join("pair"))?;
    spinner.set_message("reconstructing, lighting and rendering");

    let mut scene = Scene::new(Arc::new(Context::new(ContextOptions::default())?));
    let (left, right) = (
        Image::from_linear_rgb(&images.left),
        Image::from_linear_rgb(&images.right),
    );
    scene.set_stereo_pair(&left.view(), &right.view())?;
    scene.set_calibration(images.calibration)?;

    // Both objects stand on the reconstructed surface seen at a pixel, as a host picking pixels
    // would place them: here the pixels where the truth shows the table top and the floor.
    let world_to_camera = Mat4::from_cols_array(&images.camera_to_world).inverse();
    let camera = Camera::from_calibration(
        &images.calibration,
        images.left.width() as u32,
        images.left.height() as u32,
    )?;
    let pixel_of = |world: [f32; 3]| -> Result<Vec2> {
        camera
            .project(world_to_camera.transform_point3(Vec3::from(world)))
            .map(|(pixel, _)| pixel)
            .ok_or_else(|| Error::Internal(format!("demo point {world:?} is behind the camera")))
    };
    for (i, (what, at, size_m, yaw_deg)) in [
        ("metal-sphere", SPHERE_ON_TABLE, SPHERE_SIZE_M, 0.0),
        ("box", BOX_BESIDE_TABLE, BOX_SIZE_M, BOX_YAW_DEG),
    ]
    .into_iter()
    .enumerate()
    {
        let id = scene.add_artefact_bytes(&builtin_glb(what)?, Mat4::IDENTITY)?;
        let local = scene.artefact_bounds(id)?.local;
        // Upright along the estimated gravity: stereo vertex normals are too noisy to stand a
        // box on (DESIGN.md's placement; `Orientation::Auto` would follow them off the planes).
        let options = PlaceOptions {
            orientation: Orientation::Gravity,
            model_bounds: Some([local.min, local.max]),
            ..PlaceOptions::default()
        };
        let placed = scene.place(pixel_of(at)?, size_m, yaw_deg.to_radians(), &options);
        absorb(&mut trace, &scene);
        let placed = args.common.or_warnings(&trace, placed)?;
        scene.set_artefact_transform(id, placed.transform)?;
        if i == 0 {
            // The room's light is estimated around the sphere on the table, where it will be seen.
            scene.set_insertion_point(placed.transform.w_axis.truncate().to_array())?;
        }
    }

    let composite = scene.render(&RenderOptions::default());
    absorb(&mut trace, &scene);
    let composite = args.common.or_warnings(&trace, composite)?;
    let written = write_debug_dir(&mut scene, &composite, &args.out_dir, &mut trace);
    args.common.or_warnings(&trace, written)?;
    spinner.finish_and_clear();
    let report = args.out_dir.join("report.json");
    std::fs::write(&report, trace.report().to_json()).map_err(|e| Error::io(&report, e))?;
    if !args.common.quiet {
        eprintln!(
            "parallax demo: {} ({}×{}), intermediate products and report.json in {}",
            args.out_dir.join("composite.png").display(),
            composite.composite.width(),
            composite.composite.height(),
            args.out_dir.display()
        );
    }
    args.common.finish(&trace)
}
