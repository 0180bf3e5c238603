//! Camera calibration, the disparity ↔ depth relation, the pinhole [`Camera`] with its view and
//! projection matrices, and the depth-buffer encodings offered to hosts ([`DepthEncoding`]).
//!
//! Depth follows DESIGN.md: `Z = f·B / (d + doffs)`, metres, with `f` in pixels, `B` the baseline
//! in metres and `doffs` the x difference of the two principal points (Middlebury's `doffs`).

use std::path::Path;

use glam::{Mat4, Vec2, Vec3};

use crate::error::{Error, Result};
use crate::image::Raster;

/// Calibration of a rectified stereo pair.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StereoCalibration {
    /// Focal length in pixels (both axes: rectified images have square pixels).
    pub focal_px: f64,
    /// Principal point of the left camera, pixels (x right, y down).
    pub cx: f64,
    /// Principal point of the left camera, pixels.
    pub cy: f64,
    /// Distance between the two camera centres, metres.
    pub baseline_m: f64,
    /// `cx_right − cx_left` in pixels (0 for a symmetric rig).
    pub doffs: f64,
    /// Largest disparity worth searching, pixels, when the calibration says (Middlebury `ndisp`).
    pub max_disparity: Option<u32>,
}

impl StereoCalibration {
    /// A calibration from focal length and baseline alone, principal point at the image centre.
    ///
    /// # Errors
    /// `InvalidArgument` when a value is not finite and positive.
    pub fn from_focal_baseline(
        focal_px: f64,
        baseline_m: f64,
        width: u32,
        height: u32,
    ) -> Result<Self> {
        let c = StereoCalibration {
            focal_px,
            cx: width as f64 / 2.0,
            cy: height as f64 / 2.0,
            baseline_m,
            doffs: 0.0,
            max_disparity: None,
        };
        c.validate()?;
        Ok(c)
    }

    /// Checks that focal length and baseline are finite and positive and the offsets finite.
    ///
    /// # Errors
    /// `InvalidArgument` naming the bad value.
    pub fn validate(&self) -> Result<()> {
        let positive = |name: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(Error::invalid(format!(
                    "calibration: {name} must be finite and > 0, got {v}"
                )))
            }
        };
        positive("focal length (px)", self.focal_px)?;
        positive("baseline (m)", self.baseline_m)?;
        for (name, v) in [("cx", self.cx), ("cy", self.cy), ("doffs", self.doffs)] {
            if !v.is_finite() {
                return Err(Error::invalid(format!(
                    "calibration: {name} must be finite, got {v}"
                )));
            }
        }
        Ok(())
    }

    /// Parses a Middlebury `calib.txt` (`cam0=[f 0 cx; 0 f cy; 0 0 1]`, `doffs`, `baseline` in mm,
    /// `ndisp`; other keys ignored).
    ///
    /// # Errors
    /// `Format` for a missing or malformed key, `InvalidArgument` for non-positive values.
    pub fn parse_middlebury(text: &str) -> Result<Self> {
        let mut cam0 = None;
        let mut doffs = None;
        let mut baseline_mm = None;
        let mut ndisp = None;
        for line in text.lines() {
            let Some((key, value)) = line.split_once('=') else {
                continue;
            };
            let value = value.trim();
            match key.trim() {
                "cam0" => cam0 = Some(parse_matrix(value)?),
                "doffs" => doffs = Some(parse_number("doffs", value)?),
                "baseline" => baseline_mm = Some(parse_number("baseline", value)?),
                "ndisp" => ndisp = Some(parse_number("ndisp", value)?),
                _ => {}
            }
        }
        let cam0 = cam0.ok_or_else(|| Error::format("calib.txt: missing cam0"))?;
        let baseline_mm =
            baseline_mm.ok_or_else(|| Error::format("calib.txt: missing baseline"))?;
        let ndisp = match ndisp {
            Some(n) if n.is_finite() && n >= 1.0 && n <= u32::MAX as f64 => Some(n as u32),
            Some(n) => {
                return Err(Error::invalid(format!(
                    "calib.txt: ndisp {n} is not a positive integer"
                )))
            }
            None => None,
        };
        let c = StereoCalibration {
            focal_px: cam0[0],
            cx: cam0[2],
            cy: cam0[5],
            baseline_m: baseline_mm / 1000.0,
            doffs: doffs.unwrap_or(0.0),
            max_disparity: ndisp,
        };
        c.validate()?;
        Ok(c)
    }

    /// Reads and parses a Middlebury `calib.txt`.
    ///
    /// # Errors
    /// `Io`, or as [`StereoCalibration::parse_middlebury`].
    pub fn load_middlebury(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Self::parse_middlebury(&text).map_err(|e| match e {
            Error::Format(m) => Error::Format(format!("{}: {m}", path.display())),
            other => other,
        })
    }

    /// Depth in metres of a disparity in pixels; NaN for no estimate or a non-positive `d + doffs`.
    pub fn depth_from_disparity(&self, disparity: f32) -> f32 {
        let denominator = disparity as f64 + self.doffs;
        if disparity.is_nan() || denominator <= 0.0 {
            f32::NAN
        } else {
            (self.focal_px * self.baseline_m / denominator) as f32
        }
    }

    /// Disparity in pixels of a depth in metres (inverse of [`Self::depth_from_disparity`]).
    pub fn disparity_from_depth(&self, depth_m: f32) -> f32 {
        if depth_m.is_nan() || depth_m <= 0.0 {
            f32::NAN
        } else {
            (self.focal_px * self.baseline_m / depth_m as f64 - self.doffs) as f32
        }
    }
}

fn parse_number(key: &str, value: &str) -> Result<f64> {
    value
        .parse::<f64>()
        .map_err(|_| Error::format(format!("calib.txt: {key}={value:?} is not a number")))
}

fn parse_matrix(value: &str) -> Result<[f64; 9]> {
    let inner = value.trim_start_matches('[').trim_end_matches(']');
    let numbers: Vec<f64> = inner
        .split(|c: char| c == ';' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .map(|s| parse_number("cam0", s))
        .collect::<Result<_>>()?;
    numbers.try_into().map_err(|v: Vec<f64>| {
        Error::format(format!(
            "calib.txt: cam0 has {} numbers, expected 9",
            v.len()
        ))
    })
}

/// Horizontal field of view assumed when nothing is known about the camera: 60°, between a phone's
/// main camera (about 65–70°) and a typical compact zoom; depth from it is only right up to scale.
pub const DEFAULT_HORIZONTAL_FOV_DEG: f32 = 60.0;

/// Margin applied to the nearest valid depth when [`Camera::with_clip_from_depth`] picks the near
/// plane: `near = NEAR_MARGIN · min depth`.
pub const NEAR_MARGIN: f32 = 0.5;

/// Margin applied to the farthest valid depth: `far = FAR_MARGIN · max depth`.
pub const FAR_MARGIN: f32 = 2.0;

/// A pinhole camera: the left camera of the pair at capture, which is also the world frame.
///
/// Conventions (DESIGN.md): right-handed, +X right, +Y up, the camera looks along −Z. Image
/// coordinates are continuous pixels, origin at the top-left corner, pixel `(x, y)` centred at
/// `(x + 0.5, y + 0.5)`; a pixel `(u, v)` at depth `Z` (metres along the optical axis) is the
/// point `((u − cx)·Z/fx, −(v − cy)·Z/fy, −Z)`. A principal point off the image centre (the
/// thesis' correction matrix `C_image`, §3.2.3) is folded into [`Camera::projection_matrix`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Camera {
    /// Horizontal focal length, pixels.
    pub fx: f32,
    /// Vertical focal length, pixels.
    pub fy: f32,
    /// Principal point x, pixels from the left edge.
    pub cx: f32,
    /// Principal point y, pixels from the top edge.
    pub cy: f32,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Near clipping plane, metres (> 0).
    pub near: f32,
    /// Far clipping plane, metres (> near).
    pub far: f32,
}

/// Near plane until one is derived from depth or set: 1 cm.
const DEFAULT_NEAR: f32 = 0.01;
/// Far plane until one is derived from depth or set: 1 km.
const DEFAULT_FAR: f32 = 1000.0;

impl Camera {
    /// A camera with the given intrinsics and the default clip range (0.01–1000 m).
    ///
    /// # Errors
    /// `InvalidArgument` for a zero image size, a focal length that is not finite and > 0, or a
    /// non-finite principal point.
    pub fn new(fx: f32, fy: f32, cx: f32, cy: f32, width: u32, height: u32) -> Result<Camera> {
        let camera = Camera {
            fx,
            fy,
            cx,
            cy,
            width,
            height,
            near: DEFAULT_NEAR,
            far: DEFAULT_FAR,
        };
        camera.validate()?;
        Ok(camera)
    }

    /// The left camera of a calibrated pair, for an image of `width × height` pixels.
    ///
    /// The calibration's principal point is taken as given (continuous pixel coordinates).
    ///
    /// # Errors
    /// As [`StereoCalibration::validate`] and [`Camera::new`].
    pub fn from_calibration(
        calibration: &StereoCalibration,
        width: u32,
        height: u32,
    ) -> Result<Camera> {
        calibration.validate()?;
        let f = calibration.focal_px as f32;
        Camera::new(
            f,
            f,
            calibration.cx as f32,
            calibration.cy as f32,
            width,
            height,
        )
    }

    /// A camera with square pixels of focal length `focal_px` and the principal point at the image
    /// centre.
    ///
    /// # Errors
    /// As [`Camera::new`].
    pub fn from_focal(focal_px: f32, width: u32, height: u32) -> Result<Camera> {
        Camera::new(
            focal_px,
            focal_px,
            width as f32 / 2.0,
            height as f32 / 2.0,
            width,
            height,
        )
    }

    /// A camera whose image spans `horizontal_fov_deg` degrees across its width, square pixels,
    /// principal point at the centre.
    ///
    /// # Errors
    /// `InvalidArgument` unless `0 < horizontal_fov_deg < 180`, or as [`Camera::new`].
    pub fn from_fov(horizontal_fov_deg: f32, width: u32, height: u32) -> Result<Camera> {
        if !(horizontal_fov_deg > 0.0 && horizontal_fov_deg < 180.0) {
            return Err(Error::invalid(format!(
                "camera: horizontal field of view must be in (0°, 180°), got {horizontal_fov_deg}°"
            )));
        }
        let half = (horizontal_fov_deg as f64 / 2.0).to_radians();
        let focal = (width as f64 / 2.0) / half.tan();
        Camera::from_focal(focal as f32, width, height)
    }

    /// The camera assumed when nothing is known: [`DEFAULT_HORIZONTAL_FOV_DEG`].
    ///
    /// # Errors
    /// `InvalidArgument` for a zero image size.
    pub fn assumed(width: u32, height: u32) -> Result<Camera> {
        Camera::from_fov(DEFAULT_HORIZONTAL_FOV_DEG, width, height)
    }

    /// The same camera with another principal point (pixels).
    ///
    /// # Errors
    /// `InvalidArgument` for a non-finite value.
    pub fn with_principal_point(mut self, cx: f32, cy: f32) -> Result<Camera> {
        self.cx = cx;
        self.cy = cy;
        self.validate()?;
        Ok(self)
    }

    /// The same camera with the clip range `near..far` (metres), as a host sets it.
    ///
    /// # Errors
    /// `InvalidArgument` unless `0 < near < far` and both are finite.
    pub fn with_clip(mut self, near: f32, far: f32) -> Result<Camera> {
        validate_clip(near, far)?;
        self.near = near;
        self.far = far;
        Ok(self)
    }

    /// The same camera with its clip range derived from a depth map (metres; NaN, infinite and
    /// non-positive values ignored): `near = NEAR_MARGIN · min`, `far = FAR_MARGIN · max`, so that
    /// every valid depth lies strictly inside. (The thesis fixes near = 1 and derives far; both
    /// come from the data here.)
    ///
    /// # Errors
    /// `InvalidArgument` when the map has no valid depth.
    pub fn with_clip_from_depth(self, depth: &Raster<f32>) -> Result<Camera> {
        let (lo, hi) = valid_depth_range(depth).ok_or_else(|| {
            Error::invalid(format!(
                "camera: cannot derive near/far: the {}x{} depth map has no finite positive value",
                depth.width(),
                depth.height()
            ))
        })?;
        let near = lo * NEAR_MARGIN;
        let far = (hi * FAR_MARGIN).min(f32::MAX);
        // A depth map of one value still needs near < far.
        let far = if far > near { far } else { near * 2.0 };
        self.with_clip(near, far)
    }

    /// Checks the intrinsics and the clip range.
    ///
    /// # Errors
    /// `InvalidArgument` naming the bad value.
    pub fn validate(&self) -> Result<()> {
        if self.width == 0 || self.height == 0 {
            return Err(Error::invalid(format!(
                "camera: image size {}x{} has a zero dimension",
                self.width, self.height
            )));
        }
        for (name, v) in [("fx", self.fx), ("fy", self.fy)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::invalid(format!(
                    "camera: focal length {name} must be finite and > 0, got {v}"
                )));
            }
        }
        for (name, v) in [("cx", self.cx), ("cy", self.cy)] {
            if !v.is_finite() {
                return Err(Error::invalid(format!(
                    "camera: principal point {name} must be finite, got {v}"
                )));
            }
        }
        validate_clip(self.near, self.far)
    }

    /// Horizontal field of view, degrees.
    pub fn horizontal_fov_deg(&self) -> f32 {
        (2.0 * ((self.width as f64 / 2.0) / self.fx as f64).atan()).to_degrees() as f32
    }

    /// The 3D point (camera = world frame, metres) seen at image position `(u, v)` (continuous
    /// pixels) at depth `depth_m` along the optical axis. Non-finite or non-positive depth gives
    /// `None`.
    pub fn unproject(&self, u: f32, v: f32, depth_m: f32) -> Option<Vec3> {
        if !(depth_m.is_finite() && depth_m > 0.0) {
            return None;
        }
        let z = depth_m as f64;
        let p = Vec3::new(
            ((u as f64 - self.cx as f64) * z / self.fx as f64) as f32,
            (-(v as f64 - self.cy as f64) * z / self.fy as f64) as f32,
            -depth_m,
        );
        p.is_finite().then_some(p)
    }

    /// The unit direction of the ray through image position `(u, v)`.
    pub fn ray_direction(&self, u: f32, v: f32) -> Vec3 {
        let d = glam::DVec3::new(
            (u as f64 - self.cx as f64) / self.fx as f64,
            -(v as f64 - self.cy as f64) / self.fy as f64,
            -1.0,
        );
        d.normalize().as_vec3()
    }

    /// Image position `(u, v)` and depth (metres) of a 3D point; `None` for a point that is not in
    /// front of the camera (depth ≤ 0) or not finite. The position may lie outside the image.
    pub fn project(&self, p: Vec3) -> Option<(Vec2, f32)> {
        let depth = -p.z;
        if !(p.is_finite() && depth > 0.0) {
            return None;
        }
        let (x, y, z) = (p.x as f64, p.y as f64, depth as f64);
        let uv = Vec2::new(
            (self.cx as f64 + self.fx as f64 * x / z) as f32,
            (self.cy as f64 - self.fy as f64 * y / z) as f32,
        );
        uv.is_finite().then_some((uv, depth))
    }

    /// The pixel (column, row) a 3D point projects into and its depth (metres); `None` when the
    /// point is not in front of the camera, not finite, or projects outside the image.
    pub fn project_to_pixel(&self, p: Vec3) -> Option<(usize, usize, f32)> {
        let (uv, depth) = self.project(p)?;
        let (w, h) = (self.width as f32, self.height as f32);
        (uv.x >= 0.0 && uv.y >= 0.0 && uv.x < w && uv.y < h).then(|| {
            // `uv.x < w` can still round to `w` as an index for `uv.x` just below it.
            (
                (uv.x as usize).min(self.width as usize - 1),
                (uv.y as usize).min(self.height as usize - 1),
                depth,
            )
        })
    }

    /// The view matrix (world → camera). World is the left camera at capture (DESIGN.md), so this
    /// is the identity; it exists so hosts and the renderer compose `projection · view · model`
    /// the same way whether or not a pose is given later.
    pub fn view_matrix(&self) -> Mat4 {
        Mat4::IDENTITY
    }

    /// The projection matrix (camera → clip space) for a depth-buffer encoding, with the principal
    /// point offset folded in so that a point projects to the same pixel as [`Camera::project`]:
    /// NDC x = 2u/width − 1, NDC y = 1 − 2v/height.
    ///
    /// Depth after the perspective divide: [`DepthEncoding::OpenGlWindow`] gives OpenGL's NDC z in
    /// [−1, 1] (window depth = z/2 + 1/2, eq. 3.8); [`DepthEncoding::WebGpuZeroToOne`] gives [0, 1];
    /// [`DepthEncoding::ReversedZ`] gives 1 at near and 0 at far. [`DepthEncoding::LinearMeters`]
    /// cannot come out of a projective matrix: it returns the [0, 1] matrix, and hosts that need
    /// linear depth read it from [`depth_buffer`].
    pub fn projection_matrix(&self, encoding: DepthEncoding) -> Mat4 {
        let (w, h) = (self.width as f64, self.height as f64);
        let (n, f) = (self.near as f64, self.far as f64);
        let sx = 2.0 * self.fx as f64 / w;
        let sy = 2.0 * self.fy as f64 / h;
        let ox = 1.0 - 2.0 * self.cx as f64 / w;
        let oy = 2.0 * self.cy as f64 / h - 1.0;
        let (a, b) = match encoding {
            DepthEncoding::OpenGlWindow => (-(f + n) / (f - n), -2.0 * f * n / (f - n)),
            DepthEncoding::WebGpuZeroToOne | DepthEncoding::LinearMeters => {
                (-f / (f - n), -f * n / (f - n))
            }
            DepthEncoding::ReversedZ => (n / (f - n), n * f / (f - n)),
        };
        glam::DMat4::from_cols(
            glam::DVec4::new(sx, 0.0, 0.0, 0.0),
            glam::DVec4::new(0.0, sy, 0.0, 0.0),
            glam::DVec4::new(ox, oy, a, -1.0),
            glam::DVec4::new(0.0, 0.0, b, 0.0),
        )
        .as_mat4()
    }
}

fn validate_clip(near: f32, far: f32) -> Result<()> {
    if !(near.is_finite() && near > 0.0) {
        return Err(Error::invalid(format!(
            "camera: near plane must be finite and > 0, got {near}"
        )));
    }
    if !(far.is_finite() && far > near) {
        return Err(Error::invalid(format!(
            "camera: far plane must be finite and > near ({near}), got {far}"
        )));
    }
    Ok(())
}

/// The smallest and largest finite positive values of a depth map, if any.
pub fn valid_depth_range(depth: &Raster<f32>) -> Option<(f32, f32)> {
    depth
        .pixels()
        .iter()
        .filter(|z| z.is_finite() && **z > 0.0)
        .fold(None, |acc, &z| match acc {
            None => Some((z, z)),
            Some((lo, hi)) => Some((lo.min(z), hi.max(z))),
        })
}

/// How depth is written for a host's depth buffer. Every encoding has an exact inverse
/// ([`DepthEncoding::decode`]); the projective ones are computed in f64 and stored in f32.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[repr(C)]
pub enum DepthEncoding {
    /// Depth along the optical axis in metres (Unity/HoloLens style linear eye depth).
    LinearMeters = 0,
    /// OpenGL window depth in [0, 1] with the default depth range, thesis eq. 3.8:
    /// `z' = (F+N)/(2(F−N)) − F·N/((F−N)·z) + 1/2`.
    OpenGlWindow = 1,
    /// WebGPU / Direct3D / Vulkan depth in [0, 1]: `z' = F·(z−N)/((F−N)·z)`, 0 at near, 1 at far.
    WebGpuZeroToOne = 2,
    /// Reversed-Z in [0, 1]: `z' = N·(F−z)/((F−N)·z)`, 1 at near, 0 at far; with a float depth
    /// buffer it keeps almost constant relative precision over the whole range.
    ReversedZ = 3,
}

impl DepthEncoding {
    /// All encodings.
    pub const ALL: [DepthEncoding; 4] = [
        DepthEncoding::LinearMeters,
        DepthEncoding::OpenGlWindow,
        DepthEncoding::WebGpuZeroToOne,
        DepthEncoding::ReversedZ,
    ];

    /// The value that means "no surface here" (the buffer's clear value): `+inf` for linear
    /// metres, the far plane's value for the others (1, 1, 0).
    pub fn empty_value(self) -> f32 {
        match self {
            DepthEncoding::LinearMeters => f32::INFINITY,
            DepthEncoding::OpenGlWindow | DepthEncoding::WebGpuZeroToOne => 1.0,
            DepthEncoding::ReversedZ => 0.0,
        }
    }

    /// Encodes a depth in metres for clip planes `near < far`. Missing depth (NaN, ±inf, ≤ 0)
    /// gives [`DepthEncoding::empty_value`]; the projective encodings clamp depth to
    /// `[near, far]` so the result stays in [0, 1].
    pub fn encode(self, depth_m: f32, near: f32, far: f32) -> f32 {
        if !(depth_m.is_finite() && depth_m > 0.0) {
            return self.empty_value();
        }
        let (n, f) = (near as f64, far as f64);
        let z = (depth_m as f64).clamp(n, f);
        let value = match self {
            DepthEncoding::LinearMeters => return depth_m,
            DepthEncoding::OpenGlWindow => (f + n) / (2.0 * (f - n)) - f * n / ((f - n) * z) + 0.5,
            DepthEncoding::WebGpuZeroToOne => f * (z - n) / ((f - n) * z),
            DepthEncoding::ReversedZ => n * (f - z) / ((f - n) * z),
        };
        (value as f32).clamp(0.0, 1.0)
    }

    /// Decodes a buffer value back to depth in metres (the inverse of [`DepthEncoding::encode`]).
    /// The empty value and anything outside the encoding's range give NaN ("no depth"); the far
    /// plane's own value is the empty value, so depth exactly at `far` decodes as none.
    ///
    /// OpenGL window depth (eq. 3.8 with the default `glDepthRange(0, 1)`) and WebGPU depth are
    /// the same function of `z`; they differ in the NDC range of [`Camera::projection_matrix`]
    /// (and in how much precision a GPU keeps when it maps NDC [−1, 1] to the window).
    pub fn decode(self, value: f32, near: f32, far: f32) -> f32 {
        let (n, f, e) = (near as f64, far as f64, value as f64);
        if !value.is_finite() {
            return f32::NAN;
        }
        let z = match self {
            DepthEncoding::LinearMeters => {
                return if value > 0.0 { value } else { f32::NAN };
            }
            // eq. 3.8 solved for z: 1/z = ((F+N)/(2(F−N)) + 1/2 − z') · (F−N)/(F·N)
            DepthEncoding::OpenGlWindow | DepthEncoding::WebGpuZeroToOne => {
                if !(0.0..1.0).contains(&e) {
                    return f32::NAN;
                }
                f * n / (f - e * (f - n))
            }
            DepthEncoding::ReversedZ => {
                if !(e > 0.0 && e <= 1.0) {
                    return f32::NAN;
                }
                f * n / (e * (f - n) + n)
            }
        };
        z as f32
    }
}

/// A whole depth map (metres, NaN = none) encoded for a host's depth buffer with the camera's
/// near/far.
pub fn depth_buffer(depth: &Raster<f32>, camera: &Camera, encoding: DepthEncoding) -> Raster<f32> {
    depth.map(|&z| encoding.encode(z, camera.near, camera.far))
}

#[cfg(test)]
mod tests {
    use super::*;

    const ARTL: &str = "cam0=[1870 0 297; 0 1870 277; 0 0 1]\ncam1=[1870 0 397; 0 1870 277; 0 0 1]\ndoffs=100\nbaseline=111.53\nwidth=694\nheight=554\nndisp=256\nisint=0\nvmin=1\nvmax=200\n";

    #[test]
    fn parses_middlebury_calibration() {
        let c = StereoCalibration::parse_middlebury(ARTL).unwrap();
        assert_eq!(c.focal_px, 1870.0);
        assert_eq!((c.cx, c.cy), (297.0, 277.0));
        assert!((c.baseline_m - 0.11153).abs() < 1e-12);
        assert_eq!(c.doffs, 100.0);
        assert_eq!(c.max_disparity, Some(256));
    }

    #[test]
    fn depth_and_disparity_are_inverse() {
        let c = StereoCalibration::parse_middlebury(ARTL).unwrap();
        let z = c.depth_from_disparity(50.0);
        // Z = f·B/(d + doffs) = 1870 · 0.11153 / 150
        assert!((z as f64 - 1870.0 * 0.11153 / 150.0).abs() < 1e-6);
        assert!((c.disparity_from_depth(z) - 50.0).abs() < 1e-3);
        assert!(c.depth_from_disparity(f32::NAN).is_nan());
        assert!(c.depth_from_disparity(-100.0).is_nan());
    }

    #[test]
    fn rejects_bad_calibration() {
        assert!(matches!(
            StereoCalibration::parse_middlebury("doffs=1"),
            Err(Error::Format(_))
        ));
        assert!(StereoCalibration::parse_middlebury(
            &ARTL.replace("baseline=111.53", "baseline=-1")
        )
        .is_err());
        assert!(
            StereoCalibration::parse_middlebury(&ARTL.replace("1870 0 297", "nan 0 297")).is_err()
        );
        assert!(
            StereoCalibration::parse_middlebury(&ARTL.replace("0 0 1]\ncam1", "0]\ncam1")).is_err()
        );
        assert!(StereoCalibration::from_focal_baseline(f64::INFINITY, 0.1, 10, 10).is_err());
        assert!(StereoCalibration::from_focal_baseline(500.0, 0.0, 10, 10).is_err());
    }
}

#[cfg(test)]
mod camera_model_tests {
    use super::*;

    fn off_centre() -> Camera {
        Camera::new(800.0, 780.0, 300.0, 260.0, 640, 480)
            .unwrap()
            .with_clip(0.1, 50.0)
            .unwrap()
    }

    #[test]
    fn unproject_follows_the_design_convention() {
        let c = off_centre();
        let p = c.unproject(300.0 + 80.0, 260.0 - 39.0, 2.0).unwrap();
        // ((u − cx)·Z/fx, −(v − cy)·Z/fy, −Z)
        assert!((p - Vec3::new(0.2, 0.1, -2.0)).length() < 1e-6, "{p}");
        let (uv, z) = c.project(p).unwrap();
        assert!((uv - Vec2::new(380.0, 221.0)).length() < 1e-4);
        assert!((z - 2.0).abs() < 1e-6);
        assert!(c.unproject(10.0, 10.0, f32::NAN).is_none());
        assert!(c.unproject(10.0, 10.0, 0.0).is_none());
        assert!(c.unproject(10.0, 10.0, -1.0).is_none());
        assert!(c.unproject(10.0, 10.0, f32::INFINITY).is_none());
        assert!(c.project(Vec3::new(0.0, 0.0, 1.0)).is_none());
        let d = c.ray_direction(380.0, 221.0);
        assert!((d - p.normalize()).length() < 1e-6);
    }

    #[test]
    fn project_to_pixel_names_the_pixel_containing_the_point() {
        let c = off_centre();
        // Image position (380.3, 221.7): column 380, row 221.
        let p = c.unproject(380.3, 221.7, 2.0).unwrap();
        let (x, y, z) = c.project_to_pixel(p).unwrap();
        assert_eq!((x, y), (380, 221));
        assert!((z - 2.0).abs() < 1e-5);
        // Left of column 0, below the last row, behind the camera: no pixel.
        assert!(c
            .project_to_pixel(c.unproject(-0.5, 10.0, 2.0).unwrap())
            .is_none());
        let below = c.unproject(10.0, c.height as f32 + 0.5, 2.0).unwrap();
        assert!(c.project_to_pixel(below).is_none());
        assert!(c.project_to_pixel(Vec3::new(0.0, 0.0, 1.0)).is_none());
    }

    #[test]
    fn projection_matrix_agrees_with_project_and_encode() {
        let c = off_centre();
        let points = [
            Vec3::new(0.2, 0.1, -2.0),
            Vec3::new(-1.5, 0.7, -7.0),
            Vec3::new(3.0, -2.0, -40.0),
            Vec3::new(0.0, 0.0, -0.11),
        ];
        for enc in [
            DepthEncoding::OpenGlWindow,
            DepthEncoding::WebGpuZeroToOne,
            DepthEncoding::ReversedZ,
        ] {
            let m = c.projection_matrix(enc) * c.view_matrix();
            for p in points {
                let clip = m * p.extend(1.0);
                let ndc = clip.truncate() / clip.w;
                let pixel = Vec2::new(
                    (ndc.x + 1.0) / 2.0 * c.width as f32,
                    (1.0 - ndc.y) / 2.0 * c.height as f32,
                );
                let (uv, z) = c.project(p).unwrap();
                assert!((pixel - uv).length() < 1e-3, "{enc:?} {pixel} vs {uv}");
                let window = if enc == DepthEncoding::OpenGlWindow {
                    ndc.z * 0.5 + 0.5
                } else {
                    ndc.z
                };
                let expected = enc.encode(z, c.near, c.far);
                assert!(
                    (window - expected).abs() < 1e-5,
                    "{enc:?}: {window} vs {expected}"
                );
            }
        }
    }

    #[test]
    fn principal_point_shift_moves_the_image_not_the_ray() {
        // The thesis' C_image: a shifted principal point must shift the projected pixel by the
        // same amount, and the centre pixel must then be off the optical axis.
        let a = Camera::new(500.0, 500.0, 320.0, 240.0, 640, 480).unwrap();
        let b = a.with_principal_point(350.0, 200.0).unwrap();
        let p = Vec3::new(0.3, -0.2, -3.0);
        let (ua, _) = a.project(p).unwrap();
        let (ub, _) = b.project(p).unwrap();
        assert!((ub - ua - Vec2::new(30.0, -40.0)).length() < 1e-4);
        assert!(b.ray_direction(320.0, 240.0).x < 0.0);
        assert!(a.with_principal_point(f32::NAN, 0.0).is_err());
    }

    #[test]
    fn field_of_view_extremes_give_finite_cameras() {
        for fov in [1.0f32, 60.0, 170.0] {
            let c = Camera::from_fov(fov, 1000, 500).unwrap();
            assert!((c.horizontal_fov_deg() - fov).abs() < 1e-3, "{fov}");
            for (u, v) in [(0.0, 0.0), (1000.0, 500.0), (500.0, 250.0)] {
                let p = c.unproject(u, v, 3.0).unwrap();
                let (uv, z) = c.project(p).unwrap();
                assert!((uv - Vec2::new(u, v)).length() < 1e-2, "{fov}: {uv}");
                assert!((z - 3.0).abs() < 1e-5);
            }
            assert!(c.projection_matrix(DepthEncoding::ReversedZ).is_finite());
        }
        for bad in [0.0, 180.0, -5.0, f32::NAN] {
            assert!(Camera::from_fov(bad, 10, 10).is_err(), "{bad}");
        }
        assert!(Camera::assumed(0, 10).is_err());
        assert!((Camera::assumed(640, 480).unwrap().horizontal_fov_deg() - 60.0).abs() < 1e-3);
    }

    #[test]
    fn clip_range_is_validated() {
        let c = Camera::from_focal(500.0, 10, 10).unwrap();
        assert!(c.with_clip(1.0, 1.0).is_err());
        assert!(c.with_clip(2.0, 1.0).is_err());
        assert!(c.with_clip(0.0, 1.0).is_err());
        assert!(c.with_clip(-1.0, 1.0).is_err());
        assert!(c.with_clip(0.1, f32::INFINITY).is_err());
        assert!(c.with_clip(f32::NAN, 1.0).is_err());
        assert!(Camera::from_focal(0.0, 10, 10).is_err());
        assert!(Camera::from_focal(f32::INFINITY, 10, 10).is_err());
    }

    #[test]
    fn clip_range_from_depth_has_margins_and_skips_invalid() {
        let depth = Raster::from_vec(3, 1, vec![f32::NAN, 2.0, 8.0]);
        let c = Camera::from_focal(500.0, 3, 1)
            .unwrap()
            .with_clip_from_depth(&depth)
            .unwrap();
        assert_eq!((c.near, c.far), (2.0 * NEAR_MARGIN, 8.0 * FAR_MARGIN));
        let flat = Raster::filled(2, 2, 5.0);
        let c2 = c.with_clip_from_depth(&flat).unwrap();
        assert!(c2.near < 5.0 && c2.far > 5.0);
        let none = Raster::from_vec(2, 2, vec![f32::NAN, f32::INFINITY, -1.0, 0.0]);
        let e = c.with_clip_from_depth(&none).unwrap_err();
        assert!(e.to_string().contains("no finite positive"), "{e}");
    }

    /// The largest relative depth error that storing `z` in f32 can cause: half an ulp of the
    /// encoded value divided by the encoding's slope, plus the f32 rounding of the result.
    fn f32_bound(enc: DepthEncoding, z: f64, n: f64, f: f64) -> f64 {
        let encoded = enc.encode(z as f32, n as f32, f as f32);
        let ulp = (f32::from_bits(encoded.to_bits() + 1) - encoded) as f64;
        let slope = match enc {
            DepthEncoding::LinearMeters => 1.0,
            DepthEncoding::ReversedZ
            | DepthEncoding::OpenGlWindow
            | DepthEncoding::WebGpuZeroToOne => f * n / ((f - n) * z * z),
        };
        // Depth itself is stored in f32 before encoding: one more relative ulp of z.
        1.5 * ulp / slope / z + 2.0 * f32::EPSILON as f64
    }

    #[test]
    fn encodings_round_trip_at_extreme_near_far_ratios() {
        for exponent in 1..=7 {
            let near = 0.05f32;
            let far = near * 10f32.powi(exponent);
            for enc in DepthEncoding::ALL {
                for i in 0..=40 {
                    // Geometric steps over [near, far) (far itself is the empty value).
                    let t = i as f64 / 40.0 * 0.999;
                    let z = (near as f64 * (far as f64 / near as f64).powf(t)) as f32;
                    let e = enc.encode(z, near, far);
                    assert!(e.is_finite(), "{enc:?} 1:1e{exponent} z={z}");
                    if enc != DepthEncoding::LinearMeters {
                        assert!((0.0..=1.0).contains(&e));
                    }
                    let back = enc.decode(e, near, far);
                    let bound = f32_bound(enc, z as f64, near as f64, far as f64);
                    if back.is_nan() {
                        // Only when f32 cannot tell the depth from the far plane.
                        assert_eq!(e, enc.empty_value(), "{enc:?} 1:1e{exponent} z={z}");
                        assert!(bound > 1e-3, "{enc:?} 1:1e{exponent} z={z}: {bound}");
                        continue;
                    }
                    let rel = ((back - z) / z).abs() as f64;
                    assert!(
                        rel <= bound,
                        "{enc:?} 1:1e{exponent} z={z}: back {back}, rel {rel} > {bound}"
                    );
                }
            }
        }
    }

    #[test]
    fn reversed_z_keeps_the_most_precision_far_away() {
        let (near, far) = (0.01f32, 0.01 * 1e7);
        for z in [far * 0.5, far * 0.9, far * 0.1] {
            let err = |enc: DepthEncoding| {
                let back = enc.decode(enc.encode(z, near, far), near, far);
                if back.is_nan() {
                    f32::INFINITY
                } else {
                    ((back - z) / z).abs()
                }
            };
            let reversed = err(DepthEncoding::ReversedZ);
            assert!(reversed < 1e-5, "reversed-Z at {z}: {reversed}");
            for enc in [DepthEncoding::WebGpuZeroToOne, DepthEncoding::OpenGlWindow] {
                let e = err(enc);
                assert!(e > 100.0 * reversed && e > 1e-3, "{enc:?} at {z}: {e}");
            }
        }
    }

    #[test]
    fn missing_depth_encodes_as_empty_and_decodes_as_none() {
        for enc in DepthEncoding::ALL {
            for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 0.0, -3.0] {
                assert_eq!(
                    enc.encode(bad, 0.1, 10.0),
                    enc.empty_value(),
                    "{enc:?} {bad}"
                );
            }
            assert!(enc.decode(enc.empty_value(), 0.1, 10.0).is_nan());
            assert!(enc.decode(f32::NAN, 0.1, 10.0).is_nan());
        }
        // Beyond the clip range: clamped to the planes, never outside [0, 1].
        assert_eq!(DepthEncoding::WebGpuZeroToOne.encode(1e30, 0.1, 10.0), 1.0);
        assert_eq!(DepthEncoding::ReversedZ.encode(1e-30, 0.1, 10.0), 1.0);
        let depth = Raster::from_vec(2, 1, vec![1.0, f32::NAN]);
        let c = Camera::from_focal(100.0, 2, 1)
            .unwrap()
            .with_clip(0.5, 4.0)
            .unwrap();
        let buf = depth_buffer(&depth, &c, DepthEncoding::ReversedZ);
        assert!((buf.pixels()[0] - 0.5 * 3.0 / 3.5).abs() < 1e-6);
        assert_eq!(buf.pixels()[1], 0.0);
    }
}
