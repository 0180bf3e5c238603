//! What a reference render produces, and the Middlebury-style folder it is written to.

use glam::{Mat4, Vec3, Vec3A};
use serde::Serialize;
use std::io::BufWriter;
use std::path::Path;

use super::description::{Environment, Light, Scene};
use super::integrator::Camera;
use super::lights::equirect_to_direction;
use crate::camera::StereoCalibration;
use crate::error::{Error, Result};
use crate::image::{rec709_luma, Image, PixelFormat, Raster};

/// Size of the environment map written next to the images (equirectangular, camera frame).
pub const ENVIRONMENT_SIZE: (usize, usize) = (256, 128);

/// Counters and timings of a render.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct RenderStats {
    /// Samples per pixel actually taken (each view).
    pub samples_per_pixel: u32,
    /// Triangles in the BVH.
    pub triangles: usize,
    /// Scene preparation (tessellation, BVH, environment), seconds.
    pub build_seconds: f64,
    /// Path tracing of both views (and the ground-truth pass), seconds.
    pub render_seconds: f64,
    /// Closest-hit rays (camera, bounce and ground-truth rays).
    pub rays: u64,
    /// Shadow (any-hit) rays.
    pub shadow_rays: u64,
    /// (rays + shadow_rays) / render_seconds.
    pub rays_per_second: f64,
}

/// One light as written to `lights.json`: positions and directions in the left camera's frame
/// (x right, y up, z backwards, metres), the values of the description, and derived quantities.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LightRecord {
    /// `rect`, `sphere` or `directional`.
    #[serde(rename = "type")]
    pub kind: String,
    /// Centre in the camera frame (area lights).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub position: Option<[f32; 3]>,
    /// Emitting side of a rect light, camera frame.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub normal: Option<[f32; 3]>,
    /// Edge lengths of a rect light, metres.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub size: Option<[f32; 2]>,
    /// Radius of a sphere light, metres.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub radius: Option<f32>,
    /// Travel direction of a directional light, camera frame.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub direction: Option<[f32; 3]>,
    /// Full angular diameter of a directional light, degrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub angular_diameter_deg: Option<f32>,
    /// Emitted radiance (area lights).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub radiance: Option<[f32; 3]>,
    /// Radiant intensity: of a sphere in every direction (π r² L), of a rect along its normal (A L).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub intensity: Option<[f32; 3]>,
    /// Total emitted power (sphere 4π² r² L, rect π A L).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub power: Option<[f32; 3]>,
    /// Irradiance on a surface facing a directional light.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub irradiance: Option<[f32; 3]>,
}

impl LightRecord {
    pub(crate) fn new(light: &Light, camera: &Camera) -> LightRecord {
        let point = |p: [f32; 3]| camera.to_camera(Vec3A::from(p) - camera.eyes[0]).to_array();
        let vector = |v: Vec3A| camera.to_camera(v).to_array();
        let scale = |c: [f32; 3], k: f32| c.map(|x| x * k);
        let empty = LightRecord {
            kind: String::new(),
            position: None,
            normal: None,
            size: None,
            radius: None,
            direction: None,
            angular_diameter_deg: None,
            radiance: None,
            intensity: None,
            power: None,
            irradiance: None,
        };
        match light {
            Light::Rect {
                center,
                edge_u,
                edge_v,
                radiance,
            } => {
                let (u, v) = (Vec3A::from(*edge_u), Vec3A::from(*edge_v));
                let area = u.cross(v).length();
                LightRecord {
                    kind: "rect".into(),
                    position: Some(point(*center)),
                    normal: Some(vector(u.cross(v).normalize())),
                    size: Some([u.length(), v.length()]),
                    radiance: Some(*radiance),
                    intensity: Some(scale(*radiance, area)),
                    power: Some(scale(*radiance, area * std::f32::consts::PI)),
                    ..empty
                }
            }
            Light::Sphere {
                center,
                radius,
                radiance,
            } => {
                let pi = std::f32::consts::PI;
                LightRecord {
                    kind: "sphere".into(),
                    position: Some(point(*center)),
                    radius: Some(*radius),
                    radiance: Some(*radiance),
                    intensity: Some(scale(*radiance, pi * radius * radius)),
                    power: Some(scale(*radiance, 4.0 * pi * pi * radius * radius)),
                    ..empty
                }
            }
            Light::Directional {
                direction,
                irradiance,
                angular_diameter_deg,
            } => LightRecord {
                kind: "directional".into(),
                direction: Some(vector(Vec3A::from(*direction).normalize())),
                angular_diameter_deg: Some(*angular_diameter_deg),
                irradiance: Some(*irradiance),
                ..empty
            },
        }
    }
}

/// The truth about a rendered stereo pair.
#[derive(Debug, Clone)]
pub struct Images {
    /// The rendered scene (after the size override), as written to `scene.json`.
    pub scene: Scene,
    /// The rig: focal length and principal point in pixels, baseline in metres, doffs 0.
    pub calibration: StereoCalibration,
    /// Left view, linear RGB (1.0 = white).
    pub left: Raster<[f32; 3]>,
    /// Right view, linear RGB.
    pub right: Raster<[f32; 3]>,
    /// Disparity of the left view at each pixel centre, pixels, `f·B/Z` (NaN where no surface).
    pub disparity: Raster<f32>,
    /// Depth of the left view along the optical axis, metres (NaN where no surface).
    pub depth: Raster<f32>,
    /// Middlebury mask: 255 seen by both cameras, 128 occluded in (or outside) the right view,
    /// 0 no surface.
    pub nonocc: Raster<u8>,
    /// Unit surface normals of the left view in its camera frame (x right, y up, z towards the
    /// camera), zero where no surface.
    pub normals: Raster<[f32; 3]>,
    /// Per light: the visible fraction of the light at each pixel's surface point, weighted by
    /// the light's unoccluded contribution (1 fully lit, 0 in umbra or facing away; 1 where the
    /// pixel shows no surface).
    pub shadow: Vec<Raster<f32>>,
    /// Variance of each left pixel's mean luminance (the noise of the estimate); `None` with a
    /// single sample per pixel.
    pub variance: Option<Raster<f32>>,
    /// The lights, in the left camera's frame.
    pub lights: Vec<LightRecord>,
    /// The environment's radiance as an equirectangular map in the camera frame
    /// ([`ENVIRONMENT_SIZE`]; centre column = the camera's viewing direction, top row = camera up).
    pub environment: Raster<[f32; 3]>,
    /// Left camera → world (column-major 4×4).
    pub camera_to_world: [f32; 16],
    /// Counters and timings.
    pub stats: RenderStats,
}

#[derive(Serialize)]
struct LightsFile<'a> {
    frame: &'static str,
    units: &'static str,
    camera_to_world: [f32; 16],
    lights: &'a [LightRecord],
    environment: &'a Environment,
}

fn io_err(path: &Path) -> impl Fn(std::io::Error) -> Error + '_ {
    move |e| Error::io(path, e)
}

/// Writes a four-channel float OpenEXR.
pub(crate) fn write_exr_rgba(path: &Path, width: usize, height: usize, rgba: &[f32]) -> Result<()> {
    let file = std::fs::File::create(path).map_err(io_err(path))?;
    let encoder = image::codecs::openexr::OpenExrEncoder::new(BufWriter::new(file));
    image::ImageEncoder::write_image(
        encoder,
        bytemuck::cast_slice(rgba),
        width as u32,
        height as u32,
        image::ExtendedColorType::Rgba32F,
    )
    .map_err(|e| Error::format(format!("{}: {e}", path.display())))
}

pub(crate) fn write_gray_png(path: &Path, raster: &Raster<u8>) -> Result<()> {
    Image::from_bytes(
        raster.width() as u32,
        raster.height() as u32,
        PixelFormat::Gray8,
        raster.pixels().to_vec(),
    )?
    .save_png(path)
}

pub(crate) fn write_json(path: &Path, value: &impl Serialize) -> Result<()> {
    let text = serde_json::to_string_pretty(value)
        .map_err(|e| Error::Internal(format!("JSON for {}: {e}", path.display())))?;
    std::fs::write(path, text).map_err(io_err(path))
}

impl Images {
    /// How noisy the left view is: the median over its pixels (those with a finite, positive
    /// luminance and a finite variance) of the standard error of the pixel's luminance relative to
    /// that luminance, `√variance / luminance` (the lower median for an even count). `None` with
    /// one sample per pixel (no variance) or no such pixel.
    pub fn median_relative_noise(&self) -> Option<f64> {
        let variance = self.variance.as_ref()?;
        let mut relative: Vec<f64> = variance
            .pixels()
            .iter()
            .zip(self.left.pixels())
            .filter_map(|(&v, &rgb)| {
                let luma = rec709_luma(rgb);
                (v.is_finite() && v >= 0.0 && luma.is_finite() && luma > 0.0)
                    .then(|| (v as f64).sqrt() / luma as f64)
            })
            .collect();
        if relative.is_empty() {
            return None;
        }
        relative.sort_by(f64::total_cmp);
        // The rank ⌈n/2⌉ (1-based), as the evals' percentiles take it.
        Some(relative[relative.len().div_ceil(2) - 1])
    }

    /// `calib.txt` in Middlebury's format (baseline in millimetres; ndisp the largest disparity
    /// rounded up to a multiple of 16).
    pub fn calib_txt(&self) -> String {
        let c = &self.calibration;
        let DisparityRange { vmin, vmax, ndisp } = DisparityRange::of(&self.disparity);
        let cam = format!(
            "[{} 0 {}; 0 {} {}; 0 0 1]",
            c.focal_px, c.cx, c.focal_px, c.cy
        );
        format!(
            "cam0={cam}\ncam1={cam}\ndoffs={}\nbaseline={}\nwidth={}\nheight={}\nndisp={ndisp}\nisint=0\nvmin={}\nvmax={}\n",
            c.doffs,
            c.baseline_m * 1000.0,
            self.left.width(),
            self.left.height(),
            vmin,
            vmax,
        )
    }

    /// Writes the Middlebury layout to `dir` (created if needed): `im0.png im1.png calib.txt
    /// disp0GT.pfm mask0nocc.png`, plus `im0.exr im1.exr` (linear), `depth0GT.pfm`,
    /// `normals0GT.exr`, `shadow0GT.exr` (light i in channel i, up to four; unused channels 1),
    /// `shadow0GT_<i>.pfm` for every light, `variance0.pfm`, `lights.json`, `environment.exr`
    /// and `scene.json`.
    ///
    /// # Errors
    /// `Io` when a file cannot be written.
    pub fn write_middlebury_layout(&self, dir: impl AsRef<Path>) -> Result<()> {
        let dir = dir.as_ref();
        std::fs::create_dir_all(dir).map_err(io_err(dir))?;
        Image::from_linear_rgb(&self.left).save_png(dir.join("im0.png"))?;
        Image::from_linear_rgb(&self.right).save_png(dir.join("im1.png"))?;
        self.left.write_exr(dir.join("im0.exr"))?;
        self.right.write_exr(dir.join("im1.exr"))?;
        let calib = dir.join("calib.txt");
        std::fs::write(&calib, self.calib_txt()).map_err(io_err(&calib))?;
        self.disparity.write_pfm(dir.join("disp0GT.pfm"))?;
        self.depth.write_pfm(dir.join("depth0GT.pfm"))?;
        write_gray_png(&dir.join("mask0nocc.png"), &self.nonocc)?;
        self.normals.write_exr(dir.join("normals0GT.exr"))?;
        let (w, h) = (self.left.width(), self.left.height());
        let mut rgba = vec![1.0f32; w * h * 4];
        for (c, mask) in self.shadow.iter().take(4).enumerate() {
            for (i, v) in mask.pixels().iter().enumerate() {
                rgba[i * 4 + c] = *v;
            }
        }
        write_exr_rgba(&dir.join("shadow0GT.exr"), w, h, &rgba)?;
        for (i, mask) in self.shadow.iter().enumerate() {
            mask.write_pfm(dir.join(format!("shadow0GT_{i}.pfm")))?;
        }
        if let Some(v) = &self.variance {
            v.write_pfm(dir.join("variance0.pfm"))?;
        }
        write_json(
            &dir.join("lights.json"),
            &LightsFile {
                frame: "left camera: x right, y up, z backwards (the camera looks along -z)",
                units: "metres; radiance linear, relative to the exposure (1.0 = white)",
                camera_to_world: self.camera_to_world,
                lights: &self.lights,
                environment: &self.scene.environment,
            },
        )?;
        self.environment.write_exr(dir.join("environment.exr"))?;
        let scene = dir.join("scene.json");
        std::fs::write(&scene, self.scene.to_json()).map_err(io_err(&scene))
    }
}

/// The camera → world matrix of the left camera.
pub(crate) fn camera_to_world(camera: &Camera) -> [f32; 16] {
    Mat4::from_cols(
        Vec3::from(camera.right).extend(0.0),
        Vec3::from(camera.up).extend(0.0),
        Vec3::from(-camera.forward).extend(0.0),
        Vec3::from(camera.eyes[0]).extend(1.0),
    )
    .to_cols_array()
}

/// The environment seen from the camera as an equirectangular map in the camera frame.
pub(crate) fn environment_map(env: &super::lights::EnvLight, camera: &Camera) -> Raster<[f32; 3]> {
    let (w, h) = ENVIRONMENT_SIZE;
    Raster::from_fn(w, h, |x, y| {
        let uv = glam::Vec2::new((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
        let c = equirect_to_direction(uv);
        let world = camera.right * c.x + camera.up * c.y - camera.forward * c.z;
        env.radiance(world.normalize()).to_array()
    })
}

/// The disparity range of a rendered pair, as Middlebury's `calib.txt` states it.
pub(crate) struct DisparityRange {
    /// Smallest disparity, rounded down, pixels (0 without any).
    pub(crate) vmin: f32,
    /// Largest disparity, rounded up, pixels.
    pub(crate) vmax: f32,
    /// Disparities worth searching: above `vmax`, rounded up to a multiple of 16, at least 16.
    pub(crate) ndisp: u32,
}

impl DisparityRange {
    pub(crate) fn of(disparity: &Raster<f32>) -> DisparityRange {
        let finite = || disparity.pixels().iter().copied().filter(|d| d.is_finite());
        let vmin = finite().fold(f32::INFINITY, f32::min);
        let vmax = finite().fold(0.0f32, f32::max).ceil();
        DisparityRange {
            vmin: if vmin.is_finite() { vmin.floor() } else { 0.0 },
            vmax,
            ndisp: (((vmax as u32) / 16 + 1) * 16).max(16),
        }
    }
}
