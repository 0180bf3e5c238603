//! `parallax composite`: a stereo pair with glTF artefacts rendered in (placed on the surface
//! under a pixel), lit by the estimated or given lights, hidden behind the photo's geometry and
//! casting shadows onto it.

use std::path::{Path, PathBuf};

use glam::{Mat4, Vec2};
use parallax::artefact::{builtin_glb, BUILTIN_ARTEFACTS};
use parallax::image::{Image, Raster};
use parallax::light::{Light, LightKind};
use parallax::render::{Composite, RenderOptions, ShadingMode, ShadowMode};
use parallax::scene::Scene;
use parallax::stereo;
use parallax::trace::Trace;
use parallax::{Error, Result};

use crate::common::CommonArgs;
use crate::depth_input::{absorb, DepthInput};
use crate::previews::{lights_preview, normals_preview, surfaces_preview};

/// Arguments of `parallax composite`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    input: DepthInput,
    /// An artefact to insert: `FILE.glb@X,Y[,SIZE_M[,YAW_DEG]]` (a .glb/.gltf file, or a
    /// built-in: sphere, box, metal-sphere), standing on the surface seen at pixel (X, Y), its
    /// largest side SIZE_M metres (default 0.2), turned YAW_DEG about up. Repeatable.
    #[arg(long, value_name = "WHAT@X,Y[,SIZE_M[,YAW_DEG]]")]
    insert: Vec<String>,
    /// A light replacing the estimate (repeatable; camera frame: x right, y up, the camera looks
    /// along −z; metres; linear RGB relative to the photo's white):
    /// `directional@DX,DY,DZ@R,G,B[@SIZE_DEG]` (travel direction, irradiance),
    /// `point@X,Y,Z@R,G,B[@SIZE_M]` (position, intensity per steradian),
    /// `area@X,Y,Z@DX,DY,DZ@R,G,B[@SIZE_M]` (position, facing direction, intensity).
    #[arg(long, value_name = "KIND@…")]
    light: Vec<String>,
    /// Shading: pbr (glTF metallic-roughness) or thesis (modified Blinn-Phong).
    #[arg(long, default_value = "pbr")]
    shading: String,
    /// Shadows: esm (the thesis'), evsm, pcss or off.
    #[arg(long, default_value = "esm")]
    shadows: String,
    /// Shadow-map edge in texels (512–4096).
    #[arg(long, default_value_t = 1024)]
    shadow_map_size: u32,
    /// The composite as PNG (sRGB).
    #[arg(long, value_name = "FILE.png")]
    out: PathBuf,
    /// The artefacts' coverage as a grey PNG.
    #[arg(long, value_name = "FILE.png")]
    out_mask: Option<PathBuf>,
    /// The shadow ratio applied to the photo, as a grey PNG (1 = white).
    #[arg(long, value_name = "FILE.png")]
    out_shadow: Option<PathBuf>,
    /// Also write every intermediate product into DIR: disparity, depth, mesh normals, support
    /// surfaces, lights, shadow ratio, artefact mask and the composite (see `write_debug_dir`).
    #[arg(long, value_name = "DIR")]
    debug_dir: Option<PathBuf>,
    #[command(flatten)]
    common: CommonArgs,
}

/// One `--insert` value, parsed.
struct Insert {
    what: String,
    pixel: Vec2,
    size_m: f32,
    yaw_deg: f32,
}

fn parse_insert(text: &str) -> Result<Insert> {
    let bad = || {
        Error::invalid(format!(
            "--insert {text:?}: expected WHAT@X,Y[,SIZE_M[,YAW_DEG]], e.g. box@320,400,0.3"
        ))
    };
    let (what, numbers) = text.rsplit_once('@').ok_or_else(bad)?;
    let values = numbers
        .split(',')
        .map(|v| v.trim().parse::<f32>().map_err(|_| bad()))
        .collect::<Result<Vec<_>>>()?;
    if what.is_empty() || !(2..=4).contains(&values.len()) || values.iter().any(|v| !v.is_finite())
    {
        return Err(bad());
    }
    Ok(Insert {
        what: what.to_string(),
        pixel: Vec2::new(values[0], values[1]),
        size_m: values.get(2).copied().unwrap_or(0.2),
        yaw_deg: values.get(3).copied().unwrap_or(0.0),
    })
}

/// One `--light` value, parsed.
fn parse_light(text: &str) -> Result<Light> {
    let bad = |why: &str| {
        Error::invalid(format!(
            "--light {text:?}: {why}; expected directional@DX,DY,DZ@R,G,B[@SIZE_DEG], \
             point@X,Y,Z@R,G,B[@SIZE_M] or area@X,Y,Z@DX,DY,DZ@R,G,B[@SIZE_M]"
        ))
    };
    let mut parts = text.split('@');
    let kind = parts.next().unwrap_or_default();
    let groups = parts
        .map(|g| {
            g.split(',')
                .map(|v| v.trim().parse::<f32>().ok().filter(|v| v.is_finite()))
                .collect::<Option<Vec<f32>>>()
                .ok_or_else(|| bad("a value is not a finite number"))
        })
        .collect::<Result<Vec<_>>>()?;
    let triple = |g: &Vec<f32>| -> Result<[f32; 3]> {
        <[f32; 3]>::try_from(g.as_slice()).map_err(|_| bad("a vector needs three values"))
    };
    let scalar = |g: Option<&Vec<f32>>| -> Result<f32> {
        match g.map(|g| g.as_slice()) {
            None => Ok(0.0),
            Some([v]) => Ok(*v),
            Some(_) => Err(bad("the size is one value")),
        }
    };
    let light = match (kind, groups.len()) {
        ("directional", 2 | 3) => Light::directional(
            triple(&groups[0])?,
            scalar(groups.get(2))?,
            triple(&groups[1])?,
        ),
        ("point", 2 | 3) => Light {
            kind: LightKind::Point,
            position: triple(&groups[0])?,
            direction: [0.0, -1.0, 0.0],
            size: scalar(groups.get(2))?,
            intensity: triple(&groups[1])?,
            confidence: 1.0,
        },
        ("area", 3 | 4) => Light {
            kind: LightKind::Area,
            position: triple(&groups[0])?,
            direction: triple(&groups[1])?,
            size: scalar(groups.get(3))?,
            intensity: triple(&groups[2])?,
            confidence: 1.0,
        },
        ("directional" | "point" | "area", _) => return Err(bad("wrong number of @ groups")),
        _ => return Err(bad("unknown kind")),
    };
    Ok(light)
}

fn render_options(args: &Args) -> Result<RenderOptions> {
    let shading = match args.shading.as_str() {
        "pbr" => ShadingMode::Pbr,
        "thesis" => ShadingMode::Thesis,
        other => {
            return Err(Error::invalid(format!(
                "--shading {other:?}: pbr or thesis"
            )))
        }
    };
    let shadows = match args.shadows.as_str() {
        "esm" => ShadowMode::ThesisEsm,
        "evsm" => ShadowMode::Evsm,
        "pcss" => ShadowMode::Pcss,
        "off" => ShadowMode::Off,
        other => {
            return Err(Error::invalid(format!(
                "--shadows {other:?}: esm, evsm, pcss or off"
            )))
        }
    };
    let options = RenderOptions {
        shading,
        shadows,
        shadow_map_size: args.shadow_map_size,
        ..RenderOptions::default()
    };
    options.validate()?;
    Ok(options)
}

fn grey_png(raster: &Raster<f32>, path: &Path) -> Result<()> {
    Image::from_linear_rgb(&raster.map(|v| [v.clamp(0.0, 1.0); 3])).save_png(path)
}

/// Inserts the artefacts, renders and writes what was asked for.
pub fn run(args: Args) -> Result<()> {
    let options = render_options(&args)?;
    let inserts = args
        .insert
        .iter()
        .map(|t| parse_insert(t))
        .collect::<Result<Vec<_>>>()?;
    let lights = args
        .light
        .iter()
        .map(|t| parse_light(t))
        .collect::<Result<Vec<_>>>()?;
    let mut trace = Trace::new();
    let loaded = args.input.load(&mut trace)?;
    let mut scene = loaded.scene;
    if !lights.is_empty() {
        scene.set_lights(lights).map_err(|e| match e {
            Error::InvalidArgument(m) => Error::invalid(format!("--light: {m}")),
            other => other,
        })?;
    }
    let spinner = args.common.spinner("rendering the composite");
    for (i, insert) in inserts.iter().enumerate() {
        let id = if BUILTIN_ARTEFACTS.contains(&insert.what.as_str()) {
            scene.add_artefact_bytes(&builtin_glb(&insert.what)?, Mat4::IDENTITY)?
        } else {
            scene.add_artefact_path(&insert.what, Mat4::IDENTITY)?
        };
        let placed =
            scene.place_artefact(id, insert.pixel, insert.size_m, insert.yaw_deg.to_radians());
        absorb(&mut trace, &scene);
        args.common
            .or_warnings(&trace, placed)
            .map_err(|e| match e {
                Error::InvalidArgument(m) => {
                    Error::invalid(format!("--insert {}: {m}", insert.what))
                }
                other => other,
            })?;
        if i == 0 {
            // The room's light is estimated around the first object, where it will be seen.
            let centre = scene.artefact_bounds(id)?.world.center();
            scene.set_insertion_point(centre.to_array())?;
        }
    }
    let composite = scene.render(&options);
    absorb(&mut trace, &scene);
    let composite = args.common.or_warnings(&trace, composite)?;
    if let Some(dir) = &args.debug_dir {
        let written = write_debug_dir(&mut scene, &composite, dir, &mut trace);
        args.common.or_warnings(&trace, written)?;
    }
    spinner.finish_and_clear();
    Image::from_linear_rgb(&composite.composite).save_png(&args.out)?;
    if let Some(path) = &args.out_mask {
        grey_png(&composite.mask, path)?;
    }
    if let Some(path) = &args.out_shadow {
        grey_png(
            &composite.shadow_ratio.map(|r| (r[0] + r[1] + r[2]) / 3.0),
            path,
        )?;
    }
    args.common.finish(&trace)
}

/// Writes the products behind a composite into `dir` (created if missing), for people to look
/// at: `disparity.pfm` and `disparity.png` (when depth came from stereo), `depth.pfm` (metres),
/// `normals.png` (mesh vertex normals, xyz → rgb), `surfaces.json` and `surfaces.png`,
/// `lights.json` (the lights rendered with) and `lights.png` (shadow mask, light blobs, main
/// light direction), `shadow_ratio.png`, `mask.png` and `composite.png`. Products the render
/// reused are not recomputed; the others (e.g. surfaces) are, and appear in `trace`.
///
/// # Errors
/// `Io` when a file cannot be written; as the scene's products.
pub fn write_debug_dir(
    scene: &mut Scene,
    composite: &Composite,
    dir: &Path,
    trace: &mut Trace,
) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    if scene.host_depth().is_none() {
        let disparity = scene.disparity();
        absorb(trace, scene);
        let disparity = disparity?;
        disparity.disparity.write_pfm(dir.join("disparity.pfm"))?;
        stereo::preview::colorize(&disparity.disparity, 0.0)?
            .save_png(dir.join("disparity.png"))?;
    }
    let depth = scene.depth();
    absorb(trace, scene);
    let depth = depth?;
    depth.write_pfm(dir.join("depth.pfm"))?;
    let photo = scene.loaded_pair();
    absorb(trace, scene);
    let photo = photo?.left_rgb.clone();
    let camera = scene.camera();
    absorb(trace, scene);
    let camera = camera?;
    let mesh = scene.mesh();
    absorb(trace, scene);
    let mesh = mesh?;
    Image::from_linear_rgb(&normals_preview(&mesh, photo.width(), photo.height()))
        .save_png(dir.join("normals.png"))?;
    let surfaces = scene.surfaces();
    absorb(trace, scene);
    let surfaces = surfaces?;
    write_json(&dir.join("surfaces.json"), &*surfaces)?;
    Image::from_linear_rgb(&surfaces_preview(&photo, &depth, &camera, &surfaces))
        .save_png(dir.join("surfaces.png"))?;
    let lights = scene.lights();
    absorb(trace, scene);
    write_json(&dir.join("lights.json"), &lights?)?;
    let estimate = scene.lighting_estimate();
    absorb(trace, scene);
    Image::from_linear_rgb(&lights_preview(&photo, &*estimate?, &camera))
        .save_png(dir.join("lights.png"))?;
    grey_png(
        &composite.shadow_ratio.map(|r| (r[0] + r[1] + r[2]) / 3.0),
        &dir.join("shadow_ratio.png"),
    )?;
    grey_png(&composite.mask, &dir.join("mask.png"))?;
    Image::from_linear_rgb(&composite.composite).save_png(dir.join("composite.png"))
}

fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<()> {
    let json = serde_json::to_string_pretty(value)
        .map_err(|e| Error::Internal(format!("{}: {e}", path.display())))?;
    std::fs::write(path, json).map_err(|e| Error::io(path, e))
}
