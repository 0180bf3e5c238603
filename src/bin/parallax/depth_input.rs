//! Where `mesh` and `surfaces` get their scene: a stereo pair (matched by the scene), or a depth
//! map, or a disparity map with calibration (both given to the scene as the host's own depth, so
//! stereo is skipped).

use std::path::PathBuf;
use std::sync::Arc;

use parallax::camera::{Camera, StereoCalibration, DEFAULT_HORIZONTAL_FOV_DEG};
use parallax::context::{Context, ContextOptions};
use parallax::image::{Image, ImageLimits, Raster};
use parallax::scene::Scene;
use parallax::stereo::{Preset, StereoOptions};
use parallax::trace::Trace;
use parallax::{Error, Result};

/// Scene source and camera flags shared by the reconstruction subcommands.
#[derive(clap::Args, Debug, Clone)]
pub struct DepthInput {
    /// Left view of a rectified stereo pair (PNG/JPEG); depth comes from stereo matching.
    #[arg(
        long,
        value_name = "IMAGE",
        requires = "right",
        required_unless_present_any = ["depth", "disparity"],
        conflicts_with_all = ["depth", "disparity"]
    )]
    pub left: Option<PathBuf>,
    /// Right view of the pair (same size as --left).
    #[arg(long, value_name = "IMAGE", requires = "left")]
    pub right: Option<PathBuf>,
    /// Stereo preset with --left/--right: fast, balanced or quality (default: quality, the scene's).
    #[arg(long, value_name = "P", requires = "left")]
    pub preset: Option<Preset>,
    /// Largest disparity searched with --left/--right, pixels (default: calib.txt's ndisp, else a
    /// quarter of the width).
    #[arg(long, value_name = "N", requires = "left")]
    pub max_disparity: Option<u32>,
    /// Depth map in metres along the optical axis (PFM; inf/NaN = no depth).
    #[arg(long, value_name = "Z.pfm", conflicts_with = "disparity")]
    pub depth: Option<PathBuf>,
    /// Disparity map of the left view in pixels (PFM, Middlebury layout); needs --calib or
    /// --focal with --baseline.
    #[arg(long, value_name = "D.pfm")]
    pub disparity: Option<PathBuf>,
    /// Middlebury calib.txt: focal length, principal point, baseline, doffs (and ndisp).
    #[arg(long, value_name = "calib.txt")]
    pub calib: Option<PathBuf>,
    /// Focal length in pixels (principal point at the image centre), when there is no calib.txt.
    #[arg(long, value_name = "PX", conflicts_with = "calib")]
    pub focal: Option<f64>,
    /// Baseline in metres (with --focal, for --disparity or --left/--right).
    #[arg(long, value_name = "M", requires = "focal")]
    pub baseline: Option<f64>,
    /// Horizontal field of view in degrees assumed for --depth/--disparity when neither --calib
    /// nor --focal is given (a stereo pair without calibration assumes 60°).
    #[arg(long, value_name = "DEG", default_value_t = DEFAULT_HORIZONTAL_FOV_DEG)]
    pub fov: f32,
    /// The photo (left view): texture of the exported mesh, background of previews. Defaults to
    /// --left; must have the depth's size.
    #[arg(long, value_name = "IMAGE")]
    pub image: Option<PathBuf>,
    /// Gravity up, `X,Y,Z` in the left camera's frame (+Y up, −Z forward; any length), e.g. from
    /// an IMU: surfaces are classified against it and objects stand upright along it. Default:
    /// estimated from the near-horizontal planes.
    #[arg(long, value_name = "X,Y,Z", value_parser = crate::common::parse_vec3,
          allow_hyphen_values = true)]
    pub up: Option<[f32; 3]>,
}

/// The scene built from the command line, and the photo when there is one.
pub struct Loaded {
    pub scene: Scene,
    pub photo: Option<Image>,
}

impl DepthInput {
    /// Reads the inputs into a new scene (timed as `input.load` in `trace`).
    pub fn load(&self, trace: &mut Trace) -> Result<Loaded> {
        trace.time("input.load", "inputs given on the command line", |trace| {
            let limits = ImageLimits::default();
            let context = Arc::new(Context::new(ContextOptions {
                limits,
                ..Default::default()
            })?);
            let mut scene = Scene::new(context);
            let calibration = match (&self.calib, self.focal) {
                (Some(path), _) => Some(StereoCalibration::load_middlebury(path)?),
                (None, Some(f)) => Some(StereoCalibration {
                    focal_px: f,
                    cx: 0.0,
                    cy: 0.0,
                    baseline_m: self.baseline.unwrap_or(1.0),
                    doffs: 0.0,
                    max_disparity: None,
                }),
                (None, None) => None,
            };
            let mut photo = match &self.image {
                Some(path) => Some(Image::load(path, &limits)?),
                None => None,
            };
            let (w, h) = if let (Some(left), Some(right)) = (&self.left, &self.right) {
                let left = Image::load(left, &limits)?;
                let right = Image::load(right, &limits)?;
                scene.set_stereo_pair(&left.view(), &right.view())?;
                let (w, h) = (left.width(), left.height());
                if let Some(mut c) = calibration {
                    if self.calib.is_none() {
                        if self.baseline.is_none() {
                            return Err(Error::invalid(
                                "--left/--right with --focal also needs --baseline",
                            ));
                        }
                        // --focal puts the principal point at the image centre.
                        (c.cx, c.cy) = (w as f64 / 2.0, h as f64 / 2.0);
                    }
                    scene.set_calibration(c)?;
                }
                if self.preset.is_some() || self.max_disparity.is_some() {
                    let options = self
                        .preset
                        .map_or_else(Scene::default_stereo_options, StereoOptions::preset);
                    scene.set_stereo_options_auto_range(options, self.max_disparity)?;
                }
                photo.get_or_insert(left);
                (w, h)
            } else {
                let depth = self.read_depth(calibration.as_ref(), &limits)?;
                let (w, h) = (depth.width() as u32, depth.height() as u32);
                let camera = match (&calibration, self.focal) {
                    (Some(c), _) if self.calib.is_some() => Camera::from_calibration(c, w, h)?,
                    (_, Some(f)) => Camera::from_focal(f as f32, w, h)?,
                    _ => {
                        trace.warn(format!(
                            "no calibration: assuming a {}° horizontal field of view (depth \
                             from --disparity would need one; --depth is taken as metres)",
                            self.fov
                        ));
                        Camera::from_fov(self.fov, w, h)?
                    }
                };
                scene.set_depth(depth, None, Some(camera))?;
                (w, h)
            };
            if let (Some(p), Some(path)) = (&photo, &self.image) {
                if (p.width(), p.height()) != (w, h) {
                    return Err(Error::SizeMismatch(format!(
                        "{} is {}x{} but the depth is {w}x{h}",
                        path.display(),
                        p.width(),
                        p.height()
                    )));
                }
                if self.left.is_none() {
                    // Host depth and a photo: lights and composites work on it as on a pair.
                    scene.set_photo(&p.view())?;
                }
            }
            if let Some(up) = self.up {
                scene
                    .set_up(up)
                    .map_err(|e| Error::invalid(format!("--up: {e}")))?;
            }
            Ok(Loaded { scene, photo })
        })
    }

    /// Depth in metres from --depth, or from --disparity with the calibration.
    fn read_depth(
        &self,
        calibration: Option<&StereoCalibration>,
        limits: &ImageLimits,
    ) -> Result<Raster<f32>> {
        if let Some(path) = &self.depth {
            return Raster::read_pfm(path, limits);
        }
        let Some(path) = &self.disparity else {
            return Err(Error::invalid(
                "give --left/--right, --depth or --disparity",
            ));
        };
        let calibration = calibration.ok_or_else(|| {
            Error::invalid("--disparity needs --calib, or --focal with --baseline")
        })?;
        if self.calib.is_none() && self.baseline.is_none() {
            return Err(Error::invalid(
                "--disparity with --focal also needs --baseline",
            ));
        }
        let disparity = Raster::read_pfm(path, limits)?;
        Ok(disparity.map(|&d| calibration.depth_from_disparity(d)))
    }
}

/// Appends the trace of the scene's last call to the command's trace.
pub fn absorb(trace: &mut Trace, scene: &Scene) {
    trace.extend(scene.last_trace().clone());
}
