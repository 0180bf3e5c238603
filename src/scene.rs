//! The demand-driven pipeline (DESIGN.md, "Leave out what a scene does not need").
//!
//! A [`Scene`] holds **inputs** (each with a version number that changes when the host sets it)
//! and **products** (each cached with the versions of the inputs it was computed from). Asking
//! for a product computes it only when one of those versions changed, and every call leaves a
//! [`Trace`]: which products were computed, reused or skipped, their times and why.
//!
//! Stage modules know nothing of `Scene`; it only calls them.

use std::sync::Arc;

use crate::context::Context;
use crate::error::{Error, Result};
use crate::image::{Image, ImageView, Raster};
use crate::trace::{StageStatus, Trace};

/// A value set by the host, with the version it was set at (0 = never set).
#[derive(Debug)]
struct Input<T> {
    value: Option<T>,
    version: u64,
}

impl<T> Default for Input<T> {
    fn default() -> Self {
        Input {
            value: None,
            version: 0,
        }
    }
}

/// A cached product and the input versions it was computed from.
#[derive(Debug)]
struct Product<T> {
    value: Option<Arc<T>>,
    computed_from: Vec<u64>,
}

impl<T> Default for Product<T> {
    fn default() -> Self {
        Product {
            value: None,
            computed_from: Vec::new(),
        }
    }
}

impl<T> Product<T> {
    /// Returns the cached value when `versions` match, else computes it and caches it, recording
    /// either outcome in `trace` under `name`.
    fn get_or_compute(
        &mut self,
        name: &str,
        versions: &[u64],
        trace: &mut Trace,
        compute: impl FnOnce(&mut Trace) -> Result<T>,
    ) -> Result<Arc<T>> {
        if let Some(value) = &self.value {
            if self.computed_from == versions {
                trace.record(name, StageStatus::Reused, 0.0, "inputs unchanged");
                return Ok(Arc::clone(value));
            }
        }
        let why = if self.value.is_none() {
            "first request"
        } else {
            "an input changed"
        };
        let value = Arc::new(trace.time(name, why, compute)?);
        self.value = Some(Arc::clone(&value));
        self.computed_from = versions.to_vec();
        Ok(value)
    }
}

/// The stereo pair as the scene received it (already validated).
#[derive(Debug, Clone)]
pub struct StereoPair {
    /// Left view.
    pub left: Image,
    /// Right view.
    pub right: Image,
}

/// The stereo pair decoded into the forms the stages compute on.
#[derive(Debug, Clone)]
pub struct LoadedPair {
    /// Left view, linear RGB.
    pub left_rgb: Raster<[f32; 3]>,
    /// Left view, luminance of the encoded values in [0, 1] (what stereo matching compares).
    pub left_luma: Raster<f32>,
    /// Right view, luminance of the encoded values in [0, 1].
    pub right_luma: Raster<f32>,
}

/// A photo's reconstruction and everything inserted into it.
///
/// Not thread-safe for concurrent calls (`Send`, not `Sync`): use one scene from one thread at a
/// time; several scenes may share one [`Context`].
#[derive(Debug)]
pub struct Scene {
    context: Arc<Context>,
    next_version: u64,
    stereo_pair: Input<StereoPair>,
    calibration: Input<crate::camera::StereoCalibration>,
    loaded_pair: Product<LoadedPair>,
    last_trace: Trace,
}

impl Scene {
    /// An empty scene in `context`.
    pub fn new(context: Arc<Context>) -> Self {
        Scene {
            context,
            next_version: 0,
            stereo_pair: Input::default(),
            calibration: Input::default(),
            loaded_pair: Product::default(),
            last_trace: {
                let mut t = Trace::new();
                t.finish();
                t
            },
        }
    }

    /// The context the scene belongs to.
    pub fn context(&self) -> &Arc<Context> {
        &self.context
    }

    fn bump(&mut self) -> u64 {
        self.next_version += 1;
        self.next_version
    }

    /// Sets the rectified stereo pair, copying it in.
    ///
    /// # Errors
    /// `SizeMismatch` when the views differ in size; `InvalidArgument` for an empty view;
    /// `TooLarge` over the configured pixel cap. On error the scene is unchanged.
    pub fn set_stereo_pair(&mut self, left: &ImageView, right: &ImageView) -> Result<()> {
        let limits = self.context.limits();
        limits.check("left image", left.width() as u64, left.height() as u64)?;
        limits.check("right image", right.width() as u64, right.height() as u64)?;
        if (left.width(), left.height()) != (right.width(), right.height()) {
            return Err(Error::SizeMismatch(format!(
                "left image is {}x{} but right image is {}x{}",
                left.width(),
                left.height(),
                right.width(),
                right.height()
            )));
        }
        self.stereo_pair.value = Some(StereoPair {
            left: left.to_owned_image(),
            right: right.to_owned_image(),
        });
        self.stereo_pair.version = self.bump();
        Ok(())
    }

    /// Sets the stereo pair's calibration (focal length, principal point, baseline).
    ///
    /// # Errors
    /// `InvalidArgument` when a value is not finite or not positive; the scene is unchanged.
    pub fn set_calibration(&mut self, calibration: crate::camera::StereoCalibration) -> Result<()> {
        calibration.validate()?;
        self.calibration.value = Some(calibration);
        self.calibration.version = self.bump();
        Ok(())
    }

    /// The calibration, if the host gave one.
    pub fn calibration(&self) -> Option<&crate::camera::StereoCalibration> {
        self.calibration.value.as_ref()
    }

    /// Size of the photo (the left view), if a stereo pair was given.
    pub fn photo_size(&self) -> Option<(u32, u32)> {
        self.stereo_pair
            .value
            .as_ref()
            .map(|p| (p.left.width(), p.left.height()))
    }

    /// The stereo pair decoded for the stages (product `stereo_pair`).
    ///
    /// # Errors
    /// `NotAvailable` when no stereo pair was set.
    pub fn loaded_pair(&mut self) -> Result<Arc<LoadedPair>> {
        let mut trace = Trace::new();
        let result = self.loaded_pair_traced(&mut trace);
        trace.finish();
        self.last_trace = trace;
        result
    }

    fn loaded_pair_traced(&mut self, trace: &mut Trace) -> Result<Arc<LoadedPair>> {
        let Some(pair) = &self.stereo_pair.value else {
            return Err(Error::NotAvailable(
                "no stereo pair: set one with set_stereo_pair".into(),
            ));
        };
        let versions = [self.stereo_pair.version];
        self.loaded_pair
            .get_or_compute("stereo_pair", &versions, trace, |trace| {
                let loaded = LoadedPair {
                    left_rgb: pair.left.to_linear_rgb(),
                    left_luma: pair.left.to_luma(),
                    right_luma: pair.right.to_luma(),
                };
                if loaded.left_luma == loaded.right_luma {
                    trace
                        .warn("the left and right images are identical: every disparity will be 0");
                }
                Ok(loaded)
            })
    }

    /// The trace of the last call that asked for a product.
    pub fn last_trace(&self) -> &Trace {
        &self.last_trace
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::StereoCalibration;
    use crate::context::ContextOptions;
    use crate::image::{ImageLimits, PixelFormat};

    fn scene_with(limits: ImageLimits) -> Scene {
        Scene::new(Arc::new(
            Context::new(ContextOptions {
                limits,
                ..Default::default()
            })
            .unwrap(),
        ))
    }

    fn gray(w: u32, h: u32, seed: u8) -> Image {
        Image::from_bytes(
            w,
            h,
            PixelFormat::Gray8,
            (0..w * h)
                .map(|i| (i as u8).wrapping_mul(31).wrapping_add(seed))
                .collect(),
        )
        .unwrap()
    }

    #[test]
    fn product_is_reused_until_its_own_input_changes() {
        let mut scene = scene_with(ImageLimits::default());
        let (l, r) = (gray(8, 4, 0), gray(8, 4, 1));
        scene.set_stereo_pair(&l.view(), &r.view()).unwrap();
        let first = scene.loaded_pair().unwrap();
        assert_eq!(
            scene.last_trace().stage("stereo_pair").unwrap().status,
            StageStatus::Computed
        );

        // An unrelated input changes: the product is reused, the very same allocation.
        scene
            .set_calibration(StereoCalibration::from_focal_baseline(500.0, 0.1, 8, 4).unwrap())
            .unwrap();
        let second = scene.loaded_pair().unwrap();
        assert_eq!(
            scene.last_trace().stage("stereo_pair").unwrap().status,
            StageStatus::Reused
        );
        assert!(Arc::ptr_eq(&first, &second));

        // Its own input changes: recomputed.
        scene.set_stereo_pair(&r.view(), &l.view()).unwrap();
        let third = scene.loaded_pair().unwrap();
        assert_eq!(
            scene.last_trace().stage("stereo_pair").unwrap().status,
            StageStatus::Computed
        );
        assert_eq!(third.left_luma, second.right_luma);
    }

    #[test]
    fn bad_pairs_are_rejected_and_leave_the_scene_unchanged() {
        let mut scene = scene_with(ImageLimits { max_pixels: 32 });
        let ok = gray(8, 4, 0);
        assert!(matches!(
            scene.set_stereo_pair(&ok.view(), &gray(4, 8, 0).view()),
            Err(Error::SizeMismatch(_))
        ));
        assert!(matches!(
            scene.set_stereo_pair(&gray(9, 4, 0).view(), &gray(9, 4, 0).view()),
            Err(Error::TooLarge(_))
        ));
        assert!(scene.photo_size().is_none());
        assert!(matches!(scene.loaded_pair(), Err(Error::NotAvailable(_))));
    }

    #[test]
    fn identical_views_raise_a_warning() {
        let mut scene = scene_with(ImageLimits::default());
        let l = gray(8, 4, 3);
        scene.set_stereo_pair(&l.view(), &l.view()).unwrap();
        scene.loaded_pair().unwrap();
        assert_eq!(scene.last_trace().warnings().len(), 1);
    }
}
