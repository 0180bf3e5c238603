//! Ground-truth composites: the left view rendered with inserted objects and without them, with
//! the same random numbers, so that every path that never meets an inserted object contributes
//! identically to both and the ratio image is exactly 1 wherever the objects have no influence.

use std::path::Path;
use std::time::Instant;

use super::description::{Material, Object, Scene, Shape, Transform};
use super::outputs::write_gray_png;
use super::{accumulate, build_tracer, resolved_rig, validate_options, RenderOptions, ViewSums};
use crate::error::{Error, Result};
use crate::image::{Image, Raster};

/// Built-in objects for insertion ([`insert_shape`]).
pub const INSERT_SHAPES: &[&str] = &["sphere", "box", "cylinder", "torus"];

/// The background below this luminance counts as black: the ratio is 1 there.
const BLACK: f32 = 1e-6;

/// A built-in object to insert: `name` one of [`INSERT_SHAPES`] at unit scale (about 0.2 m
/// tall), its lowest point resting on `position` (world metres), scaled by `scale` and turned
/// `yaw_deg` about +Y. Sphere: glossy red plastic; box: diffuse blue with a checker; cylinder:
/// diffuse green; torus: rough gold metal.
///
/// # Errors
/// `InvalidArgument` for an unknown name or a non-finite/non-positive scale or position.
pub fn insert_shape(name: &str, position: [f32; 3], scale: f32, yaw_deg: f32) -> Result<Object> {
    if !(scale.is_finite() && scale > 0.0) {
        return Err(Error::invalid(format!(
            "insert scale must be finite and > 0, got {scale}"
        )));
    }
    if !position.iter().all(|c| c.is_finite()) || !yaw_deg.is_finite() {
        return Err(Error::invalid(format!(
            "insert position {position:?} and yaw {yaw_deg} must be finite"
        )));
    }
    let (shape, material, half_height) = match name {
        "sphere" => (
            Shape::Sphere {
                radius: 0.1,
                segments: Some(64),
            },
            Material {
                base_color: [0.7, 0.08, 0.06],
                roughness: 0.25,
                ..Material::default()
            },
            0.1,
        ),
        "box" => (
            Shape::Box {
                size: [0.2, 0.2, 0.2],
            },
            Material {
                base_color: [0.1, 0.2, 0.6],
                texture: Some(super::description::Texture {
                    pattern: super::description::Pattern::Checker,
                    scale: 20.0,
                    color: [0.6, 0.6, 0.65],
                    speckle: 0.1,
                }),
                ..Material::default()
            },
            0.1,
        ),
        "cylinder" => (
            Shape::Cylinder {
                radius: 0.06,
                height: 0.2,
                segments: Some(64),
            },
            Material::diffuse([0.15, 0.5, 0.15]),
            0.1,
        ),
        "torus" => (
            Shape::Torus {
                major_radius: 0.1,
                minor_radius: 0.035,
                segments: Some(64),
            },
            Material {
                base_color: [1.0, 0.78, 0.34],
                metallic: 1.0,
                roughness: 0.35,
                ..Material::default()
            },
            0.035,
        ),
        other => {
            return Err(Error::invalid(format!(
                "unknown insert shape {other:?}; built-in shapes: {}",
                INSERT_SHAPES.join(", ")
            )))
        }
    };
    Ok(Object {
        name: format!("inserted {name}"),
        shape,
        material,
        transform: Transform {
            translation: [position[0], position[1] + half_height * scale, position[2]],
            rotation_deg: [yaw_deg, 0.0, 0.0],
            scale: [scale; 3],
        },
    })
}

/// A ground-truth composite of the left view.
#[derive(Debug, Clone)]
pub struct Composite {
    /// The scene with the inserted objects, linear RGB.
    pub composite: Raster<[f32; 3]>,
    /// The scene without them, linear RGB (same random numbers).
    pub background: Raster<[f32; 3]>,
    /// Per channel `composite / background`: below 1 where the objects shadow or block light,
    /// above 1 where they reflect light onto the scene, exactly 1 where they have no influence and
    /// where the background is black. On the objects' own pixels it compares them with what they
    /// hide; use `mask` there.
    pub ratio: Raster<[f32; 3]>,
    /// Fraction of each pixel covered by inserted objects, in [0, 1].
    pub mask: Raster<f32>,
    /// Samples per pixel taken.
    pub samples_per_pixel: u32,
    /// Wall-clock time of both renders, seconds.
    pub render_seconds: f64,
}

/// Renders the left view of `scene` with the `inserted` objects and without them.
///
/// # Errors
/// As [`super::render`]; `InvalidArgument` naming an invalid inserted object.
pub fn render_composite(
    scene: &Scene,
    inserted: &[Object],
    options: &RenderOptions,
) -> Result<Composite> {
    validate_options(options)?;
    let mut with = scene.clone();
    with.objects.extend(inserted.iter().cloned());
    with.validate().map_err(|e| match e {
        Error::InvalidArgument(m) => Error::invalid(format!("with inserted objects: {m}")),
        other => other,
    })?;
    let (camera, resolved) = resolved_rig(scene, options)?;
    let start = Instant::now();
    let background_tracer = build_tracer(&resolved, camera, &[], options.max_bounces)?;
    let composite_tracer = build_tracer(&resolved, camera, inserted, options.max_bounces)?;
    let mut background = ViewSums::new(&background_tracer, false);
    let mut composite = ViewSums::new(&composite_tracer, false);
    // With a time budget both renders must take the same count: the composite decides, the
    // background then takes exactly as many.
    let (spp, _) = accumulate(&composite_tracer, &mut [(0, &mut composite)], options);
    let fixed = RenderOptions {
        samples: super::SampleBudget::PerPixel(spp),
        ..*options
    };
    accumulate(&background_tracer, &mut [(0, &mut background)], &fixed);
    let composite_image = composite.mean(&camera, spp);
    let background_image = background.mean(&camera, spp);
    let ratio = Raster::from_vec(
        camera.width,
        camera.height,
        composite_image
            .pixels()
            .iter()
            .zip(background_image.pixels())
            .map(|(c, b)| {
                let mut r = [1.0f32; 3];
                for k in 0..3 {
                    if b[k] > BLACK {
                        r[k] = (c[k] / b[k]).min(1e6);
                    }
                }
                r
            })
            .collect(),
    );
    let mask = Raster::from_vec(
        camera.width,
        camera.height,
        composite
            .pixels
            .iter()
            .map(|p| p.inserted as f32 / spp as f32)
            .collect(),
    );
    Ok(Composite {
        composite: composite_image,
        background: background_image,
        ratio,
        mask,
        samples_per_pixel: spp,
        render_seconds: start.elapsed().as_secs_f64(),
    })
}

impl Composite {
    /// Writes `composite_gt.png` (sRGB), `composite_gt.exr`, `background_gt.exr`, `ratio_gt.exr`
    /// and `mask_gt.png` (coverage × 255) into `dir` (created if needed).
    ///
    /// # Errors
    /// `Io` when a file cannot be written.
    pub fn write(&self, dir: impl AsRef<Path>) -> Result<()> {
        let dir = dir.as_ref();
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        Image::from_linear_rgb(&self.composite).save_png(dir.join("composite_gt.png"))?;
        self.composite.write_exr(dir.join("composite_gt.exr"))?;
        self.background.write_exr(dir.join("background_gt.exr"))?;
        self.ratio.write_exr(dir.join("ratio_gt.exr"))?;
        let mask = self.mask.map(|m| (m.clamp(0.0, 1.0) * 255.0).round() as u8);
        write_gray_png(&dir.join("mask_gt.png"), &mask)
    }
}
