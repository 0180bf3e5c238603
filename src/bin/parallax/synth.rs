//! `parallax synth`: renders a synthetic stereo scene with the reference path tracer and writes
//! its ground truth in the Middlebury layout (and ground-truth composites with `--insert`).

use std::path::PathBuf;
use std::time::Duration;

use parallax::reference::{self, Object, RenderOptions, SampleBudget, Scene};
use parallax::trace::{StageStatus, Trace};
use parallax::Error;

use crate::common::CommonArgs;

/// Arguments of `parallax synth`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// A built-in scene (room, two-lights, clutter, window) or a scene description (.json).
    #[arg(long, value_name = "NAME|FILE.json")]
    scene: String,
    /// Output folder (created if needed).
    #[arg(long, value_name = "DIR")]
    out_dir: PathBuf,
    /// Image width in pixels (default: the scene's; the field of view is kept).
    #[arg(long)]
    width: Option<u32>,
    /// Image height in pixels (default: the scene's aspect ratio).
    #[arg(long)]
    height: Option<u32>,
    /// Samples per pixel (default 16).
    #[arg(long, conflicts_with = "seconds")]
    spp: Option<u32>,
    /// Render for about this many seconds instead of a fixed sample count.
    #[arg(long)]
    seconds: Option<f64>,
    /// Most surface interactions per path.
    #[arg(long, default_value_t = 8)]
    bounces: u32,
    /// Seed of the random numbers.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Insert an object and also write the ground-truth composite: SHAPE@x,y,z[,scale[,yaw_deg]]
    /// with SHAPE one of sphere, box, cylinder, torus (its lowest point rests on x,y,z, world
    /// metres), a glTF model FILE.glb or FILE.gltf (its lowest point rests on x,y,z, centred over
    /// it; scale = its largest extent in metres, default its own size; textures enter by their
    /// mean colour) or an object description FILE.json (its origin goes to x,y,z). Repeatable.
    #[arg(long, value_name = "SHAPE_OR_FILE@x,y,z[,scale[,yaw]]")]
    insert: Vec<String>,
    #[command(flatten)]
    common: CommonArgs,
}

/// Parses one `--insert` value into the objects it inserts (a glTF model gives one per primitive).
fn parse_insert(spec: &str) -> parallax::Result<Vec<Object>> {
    let (what, place) = spec.rsplit_once('@').ok_or_else(|| {
        Error::invalid(format!(
            "--insert {spec:?}: expected SHAPE_OR_FILE@x,y,z[,scale[,yaw]]"
        ))
    })?;
    let numbers: Vec<f32> = place
        .split(',')
        .map(|s| {
            s.trim()
                .parse::<f32>()
                .map_err(|_| Error::invalid(format!("--insert {spec:?}: {s:?} is not a number")))
        })
        .collect::<parallax::Result<_>>()?;
    if !(3..=5).contains(&numbers.len()) {
        return Err(Error::invalid(format!(
            "--insert {spec:?}: expected 3 to 5 numbers (x,y,z[,scale[,yaw]]), got {}",
            numbers.len()
        )));
    }
    let position = [numbers[0], numbers[1], numbers[2]];
    let size = numbers.get(3).copied();
    let scale = size.unwrap_or(1.0);
    let yaw = numbers.get(4).copied().unwrap_or(0.0);
    let lower = what.to_ascii_lowercase();
    if lower.ends_with(".glb") || lower.ends_with(".gltf") {
        return insert_gltf(what, position, size, yaw);
    }
    if lower.ends_with(".json") {
        let text = std::fs::read_to_string(what).map_err(|e| Error::io(what, e))?;
        let mut object: Object = serde_json::from_str(&text)
            .map_err(|e| Error::format(format!("{what}: object description: {e}")))?;
        // The placement replaces the file's translation and rotation; its scale is multiplied.
        object.transform = reference::Transform {
            translation: position,
            rotation_deg: [yaw, 0.0, 0.0],
            scale: object.transform.scale.map(|s| s * scale),
        };
        return Ok(vec![object]);
    }
    Ok(vec![reference::insert_shape(what, position, scale, yaw)?])
}

/// The objects of a glTF model's primitives (see [`reference::insert_artefact`]).
#[cfg(feature = "gltf")]
fn insert_gltf(
    path: &str,
    position: [f32; 3],
    size: Option<f32>,
    yaw: f32,
) -> parallax::Result<Vec<Object>> {
    use parallax::artefact::{Artefact, LoadOptions};
    let artefact = Artefact::from_path(path, &LoadOptions::default())?;
    for w in &artefact.warnings {
        eprintln!("parallax: {path}: {w}");
    }
    reference::insert_artefact(&artefact, position, size, yaw)
}

#[cfg(not(feature = "gltf"))]
fn insert_gltf(
    path: &str,
    _position: [f32; 3],
    _size: Option<f32>,
    _yaw: f32,
) -> parallax::Result<Vec<Object>> {
    Err(Error::Unsupported(format!(
        "--insert {path}: this build has no glTF support (cargo feature \"gltf\")"
    )))
}

/// Renders the scene and writes the ground truth (see the module documentation).
pub fn run(args: Args) -> parallax::Result<()> {
    let mut trace = Trace::new();
    let scene = if reference::BUILTIN_SCENES.contains(&args.scene.as_str()) {
        reference::builtin(&args.scene)?
    } else if args.scene.to_ascii_lowercase().ends_with(".json") {
        Scene::load(&args.scene)?
    } else {
        return Err(Error::invalid(format!(
            "--scene {:?}: neither a built-in scene ({}) nor a .json file",
            args.scene,
            reference::BUILTIN_SCENES.join(", ")
        )));
    };
    let inserts: Vec<Object> = args
        .insert
        .iter()
        .map(|s| parse_insert(s))
        .collect::<parallax::Result<Vec<_>>>()?
        .into_iter()
        .flatten()
        .collect();
    let samples = match (args.spp, args.seconds) {
        (_, Some(s)) if !(s.is_finite() && s > 0.0 && s < 1e7) => {
            return Err(Error::invalid(format!(
                "--seconds must be a positive number of seconds, got {s}"
            )))
        }
        (_, Some(s)) => SampleBudget::Time(Duration::from_secs_f64(s)),
        (Some(n), None) => SampleBudget::PerPixel(n),
        (None, None) => SampleBudget::PerPixel(16),
    };
    let options = RenderOptions {
        width: args.width,
        height: args.height,
        samples,
        max_bounces: args.bounces,
        seed: args.seed,
    };

    let spinner = args.common.spinner(&format!("rendering {}", args.scene));
    let images = reference::render(&scene, &options);
    spinner.finish_and_clear();
    let images = images?;
    let s = images.stats;
    trace.record(
        "synth.build",
        StageStatus::Computed,
        s.build_seconds * 1e3,
        format!("{} triangles, BVH", s.triangles),
    );
    trace.record(
        "synth.render",
        StageStatus::Computed,
        s.render_seconds * 1e3,
        format!(
            "{}x{} stereo pair, {} spp, {} rays + {} shadow rays, {:.2} Mrays/s",
            images.left.width(),
            images.left.height(),
            s.samples_per_pixel,
            s.rays,
            s.shadow_rays,
            s.rays_per_second / 1e6
        ),
    );
    trace.time("synth.write", "Middlebury layout", |_| {
        images.write_middlebury_layout(&args.out_dir)
    })?;
    let stats_path = args.out_dir.join("render_stats.json");
    std::fs::write(
        &stats_path,
        serde_json::to_string_pretty(&s).unwrap_or_default(),
    )
    .map_err(|e| Error::io(&stats_path, e))?;
    if !args.common.quiet {
        eprintln!(
            "parallax: {} {}x{}: {} spp in {:.2} s ({:.2} Mrays/s) -> {}",
            images.scene.name,
            images.left.width(),
            images.left.height(),
            s.samples_per_pixel,
            s.render_seconds,
            s.rays_per_second / 1e6,
            args.out_dir.display()
        );
    }

    if !inserts.is_empty() {
        let spinner = args.common.spinner("rendering the ground-truth composite");
        // Same sample count as the pair, so a time budget is not spent twice over.
        let composite_options = RenderOptions {
            samples: SampleBudget::PerPixel(s.samples_per_pixel),
            ..options
        };
        let composite = reference::render_composite(&scene, &inserts, &composite_options);
        spinner.finish_and_clear();
        let composite = composite?;
        trace.record(
            "synth.composite",
            StageStatus::Computed,
            composite.render_seconds * 1e3,
            format!(
                "{} inserted object(s), with and without, {} spp",
                inserts.len(),
                composite.samples_per_pixel
            ),
        );
        trace.time("synth.write_composite", "composite outputs", |_| {
            composite.write(&args.out_dir)
        })?;
    }
    args.common.finish(&trace)
}
