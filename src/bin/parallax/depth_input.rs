//! Where `mesh` and `surfaces` get their depth and camera: a depth map, or a disparity map with
//! calibration. (The stereo front end, `--left/--right`, plugs in here as a third source.)

use std::path::PathBuf;

use parallax::camera::{Camera, StereoCalibration, DEFAULT_HORIZONTAL_FOV_DEG};
use parallax::image::{Image, ImageLimits, Raster};
use parallax::trace::Trace;
use parallax::{Error, Result};

/// Depth source and camera flags shared by the reconstruction subcommands.
#[derive(clap::Args, Debug, Clone)]
pub struct DepthInput {
    /// Depth map in metres along the optical axis (PFM; inf/NaN = no depth).
    #[arg(
        long,
        value_name = "Z.pfm",
        required_unless_present = "disparity",
        conflicts_with = "disparity"
    )]
    pub depth: Option<PathBuf>,
    /// Disparity map of the left view in pixels (PFM, Middlebury layout); needs --calib or
    /// --focal with --baseline.
    #[arg(long, value_name = "D.pfm")]
    pub disparity: Option<PathBuf>,
    /// Middlebury calib.txt: focal length, principal point, baseline, doffs.
    #[arg(long, value_name = "calib.txt")]
    pub calib: Option<PathBuf>,
    /// Focal length in pixels (principal point at the image centre), when there is no calib.txt.
    #[arg(long, value_name = "PX", conflicts_with = "calib")]
    pub focal: Option<f64>,
    /// Baseline in metres (with --focal, for --disparity).
    #[arg(long, value_name = "M", requires = "focal")]
    pub baseline: Option<f64>,
    /// Horizontal field of view in degrees assumed when neither --calib nor --focal is given.
    #[arg(long, value_name = "DEG", default_value_t = DEFAULT_HORIZONTAL_FOV_DEG)]
    pub fov: f32,
    /// The photo (left view): texture of the exported mesh, background of previews. Must have the
    /// depth map's size.
    #[arg(long, value_name = "IMAGE")]
    pub image: Option<PathBuf>,
}

/// What the source gave.
pub struct Loaded {
    pub depth: Raster<f32>,
    pub camera: Camera,
    pub photo: Option<Image>,
}

impl DepthInput {
    /// Reads the inputs and derives depth (metres) and the camera (near/far from the depth).
    pub fn load(&self, trace: &mut Trace) -> Result<Loaded> {
        let limits = ImageLimits::default();
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
        let depth = trace.time(
            "depth.load",
            "depth source given on the command line",
            |_| {
                if let Some(path) = &self.depth {
                    return Raster::read_pfm(path, &limits);
                }
                let Some(path) = &self.disparity else {
                    return Err(Error::invalid("give --depth or --disparity"));
                };
                let calibration = calibration.ok_or_else(|| {
                    Error::invalid("--disparity needs --calib, or --focal with --baseline")
                })?;
                if self.calib.is_none() && self.baseline.is_none() {
                    return Err(Error::invalid(
                        "--disparity with --focal also needs --baseline",
                    ));
                }
                let disparity = Raster::read_pfm(path, &limits)?;
                Ok(disparity.map(|&d| calibration.depth_from_disparity(d)))
            },
        )?;
        let (w, h) = (depth.width() as u32, depth.height() as u32);
        let camera = match (&calibration, self.focal) {
            (Some(c), _) if self.calib.is_some() => Camera::from_calibration(c, w, h)?,
            (_, Some(f)) => Camera::from_focal(f as f32, w, h)?,
            _ => {
                trace.warn(format!(
                    "no calibration: assuming a {}° horizontal field of view (depth from \
                     --disparity would need one; --depth is taken as metres)",
                    self.fov
                ));
                Camera::from_fov(self.fov, w, h)?
            }
        };
        let camera = camera.with_clip_from_depth(&depth)?;
        let photo = match &self.image {
            Some(path) => {
                let photo = Image::load(path, &limits)?;
                if (photo.width(), photo.height()) != (w, h) {
                    return Err(Error::SizeMismatch(format!(
                        "{} is {}x{} but the depth map is {w}x{h}",
                        path.display(),
                        photo.width(),
                        photo.height()
                    )));
                }
                Some(photo)
            }
            None => None,
        };
        Ok(Loaded {
            depth,
            camera,
            photo,
        })
    }
}
