//! The demand-driven pipeline (DESIGN.md, "Leave out what a scene does not need").
//!
//! A [`Scene`] holds **inputs** (each with a version number that changes when the host sets it)
//! and **products** (each cached with the versions of the inputs it was computed from). Asking
//! for a product computes it only when one of those versions changed, and every call leaves a
//! [`Trace`]: which products were computed, reused or skipped, their times and why.
//!
//! Stage modules know nothing of `Scene`; it only calls them.

use std::sync::Arc;

use crate::camera::{Camera, StereoCalibration};
use crate::context::Context;
use crate::error::{Error, Result};
use crate::image::{Image, ImageView, Raster};
use crate::stereo::{self, Disparity, StereoOptions};
use crate::trace::{Observer, StageStatus, Trace};

/// Share of the pixels with nothing to match (`StereoStats::textureless_fraction`) beyond which
/// the trace warns: most of the depth is then the matcher's guess. Photographs and the built-in
/// renders have 0.2–0.3 % (the first column or two, where one disparity lies inside the right
/// view); a flat pair has 100 %.
const MOSTLY_TEXTURELESS: f32 = 0.5;

/// A value set by the host, with the version it was set at (0 = never set).
#[derive(Debug, Clone)]
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
    /// Incremented on every recomputation: the version downstream products depend on.
    generation: u64,
}

impl<T> Default for Product<T> {
    fn default() -> Self {
        Product {
            value: None,
            computed_from: Vec::new(),
            generation: 0,
        }
    }
}

// Not derived: a clone shares the cached value (an `Arc`) whatever `T` is.
impl<T> Clone for Product<T> {
    fn clone(&self) -> Self {
        Product {
            value: self.value.clone(),
            computed_from: self.computed_from.clone(),
            generation: self.generation,
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
        self.get_or_share(name, versions, trace, |trace| compute(trace).map(Arc::new))
    }

    /// [`Product::get_or_compute`] for a computation that returns a shared value (one that
    /// another product or an input already holds), so it is not copied.
    fn get_or_share(
        &mut self,
        name: &str,
        versions: &[u64],
        trace: &mut Trace,
        compute: impl FnOnce(&mut Trace) -> Result<Arc<T>>,
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
        trace.progress(name, 0.0)?;
        let value = trace.time(name, why, compute)?;
        self.value = Some(Arc::clone(&value));
        self.computed_from = versions.to_vec();
        self.generation += 1;
        trace.progress(name, 1.0)?;
        Ok(value)
    }
}

/// The stereo pair as the scene received it (already validated).
#[derive(Debug, Clone)]
pub struct StereoPair {
    /// Left view: the photo.
    pub left: Image,
    /// Right view; `None` when the host gave only the photo ([`Scene::set_photo`]).
    pub right: Option<Image>,
}

/// The stereo pair decoded into the forms the stages compute on.
#[derive(Debug, Clone)]
pub struct LoadedPair {
    /// Left view, linear RGB.
    pub left_rgb: Raster<[f32; 3]>,
    /// Left view, luminance of the encoded values in [0, 1] (what stereo matching compares).
    pub left_luma: Raster<f32>,
    /// Right view, luminance of the encoded values in [0, 1]; `None` for a photo alone.
    pub right_luma: Option<Raster<f32>>,
}

/// Stereo options as the host set them; `max_disparity: None` = choose automatically.
#[derive(Debug, Clone)]
struct StereoSettings {
    options: StereoOptions,
    max_disparity: Option<u32>,
}

impl Default for StereoSettings {
    fn default() -> Self {
        StereoSettings {
            options: Scene::default_stereo_options(),
            max_disparity: None,
        }
    }
}

#[cfg(feature = "gltf")]
mod artefacts;
mod lighting;
mod reconstruction;
#[cfg(all(feature = "gpu", feature = "gltf"))]
mod render;

#[cfg(all(test, feature = "gltf"))]
pub(crate) use artefacts::box_glb;
#[cfg(feature = "gltf")]
pub use artefacts::ArtefactBounds;
pub use lighting::MAX_LIGHTS;
pub use reconstruction::HostDepth;

/// A photo's reconstruction and everything inserted into it.
///
/// Not thread-safe for concurrent calls (`Send`, not `Sync`): use one scene from one thread at a
/// time; several scenes may share one [`Context`].
///
/// Cloning is cheap: the clone shares every cached product and the input images (`Arc`s), so
/// several compositions of one reconstruction can go on side by side without redoing it; each
/// copy then changes independently.
#[derive(Debug, Clone)]
pub struct Scene {
    context: Arc<Context>,
    next_version: u64,
    stereo_pair: Input<Arc<StereoPair>>,
    calibration: Input<StereoCalibration>,
    stereo_options: Input<StereoSettings>,
    host_depth: Input<HostDepth>,
    clip: Input<(f32, f32)>,
    mesh_options: Input<crate::mesh::MeshOptions>,
    surface_options: Input<crate::mesh::SurfaceOptions>,
    /// Gravity up from the host (an IMU), camera frame, unit.
    host_up: Input<glam::Vec3>,
    loaded_pair: Product<LoadedPair>,
    disparity: Product<Disparity>,
    depth: Product<Raster<f32>>,
    camera: Product<Camera>,
    depth_buffer: Product<Raster<f32>>,
    grid_mesh: Product<crate::mesh::SceneMesh>,
    /// The grid mesh with its normals snapped to the surfaces found on it.
    snapped_mesh: Product<crate::mesh::SceneMesh>,
    mesh: Product<crate::mesh::SceneMesh>,
    bvh: Product<crate::mesh::Bvh>,
    surfaces: Product<crate::mesh::Surfaces>,
    #[cfg(feature = "gltf")]
    artefacts: artefacts::SceneArtefacts,
    lighting: lighting::SceneLighting,
    last_trace: Trace,
    /// The host's progress/log hook, handed to each call's trace ([`Scene::set_observer`]).
    observer: Option<Observer>,
}

impl Scene {
    /// An empty scene in `context`.
    pub fn new(context: Arc<Context>) -> Self {
        Scene {
            context,
            next_version: 0,
            stereo_pair: Input::default(),
            calibration: Input::default(),
            stereo_options: Input::default(),
            host_depth: Input::default(),
            clip: Input::default(),
            mesh_options: Input::default(),
            surface_options: Input::default(),
            host_up: Input::default(),
            loaded_pair: Product::default(),
            disparity: Product::default(),
            depth: Product::default(),
            camera: Product::default(),
            depth_buffer: Product::default(),
            grid_mesh: Product::default(),
            snapped_mesh: Product::default(),
            mesh: Product::default(),
            bvh: Product::default(),
            surfaces: Product::default(),
            #[cfg(feature = "gltf")]
            artefacts: artefacts::SceneArtefacts::default(),
            lighting: lighting::SceneLighting::default(),
            last_trace: {
                let mut t = Trace::new();
                t.finish();
                t
            },
            observer: None,
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
    /// `TooLarge` over the configured pixel cap; `SizeMismatch` when a host depth map of another
    /// size was set ([`Scene::set_depth`]). On error the scene is unchanged.
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
        self.set_views(left, Some(right), "the stereo pair")
    }

    /// Sets the photo alone, copying it in: for a host that gives its own depth
    /// ([`Scene::set_depth`], e.g. from ARCore or a depth camera) and wants the lighting estimate
    /// and composites on this photo. Stereo matching then has nothing to match and answers
    /// `NotAvailable`; everything downstream of depth works as with a pair.
    ///
    /// # Errors
    /// `InvalidArgument` for an empty image; `TooLarge` over the configured pixel cap;
    /// `SizeMismatch` when a host depth map of another size was set. On error the scene is
    /// unchanged.
    pub fn set_photo(&mut self, photo: &ImageView) -> Result<()> {
        self.context
            .limits()
            .check("photo", photo.width() as u64, photo.height() as u64)?;
        self.set_views(photo, None, "the photo")
    }

    /// Keeps the views (already checked against the pixel cap); `what` names them in errors.
    fn set_views(&mut self, left: &ImageView, right: Option<&ImageView>, what: &str) -> Result<()> {
        if let Some(host) = &self.host_depth.value {
            let size = (host.depth.width() as u32, host.depth.height() as u32);
            if size != (left.width(), left.height()) {
                return Err(Error::SizeMismatch(format!(
                    "{what} is {}x{} but the host depth map is {}x{}",
                    left.width(),
                    left.height(),
                    size.0,
                    size.1
                )));
            }
        }
        self.stereo_pair.value = Some(Arc::new(StereoPair {
            left: left.to_owned_image(),
            right: right.map(ImageView::to_owned_image),
        }));
        self.stereo_pair.version = self.bump();
        Ok(())
    }

    /// Sets the stereo pair's calibration (focal length, principal point, baseline).
    ///
    /// # Errors
    /// `InvalidArgument` when a value is not finite or not positive; the scene is unchanged.
    pub fn set_calibration(&mut self, calibration: StereoCalibration) -> Result<()> {
        calibration.validate()?;
        self.calibration.value = Some(calibration);
        self.calibration.version = self.bump();
        Ok(())
    }

    /// The calibration, if the host gave one.
    pub fn calibration(&self) -> Option<&StereoCalibration> {
        self.calibration.value.as_ref()
    }

    /// The stereo options a scene matches with unless the host sets its own: the `quality`
    /// preset, not the matcher's default `balanced`. The scene's mesh normals, planes and
    /// placements need `quality`'s sub-pixel precision on noisy photographs (on the built-in
    /// 16-spp renders, `balanced` moved `room`'s floor placement from +0.65 % to +5.4 % of the
    /// distance and left `clutter`'s up to the camera fallback; docs/stereo-eval.md, stop 39).
    pub fn default_stereo_options() -> StereoOptions {
        StereoOptions::preset(Self::DEFAULT_STEREO_PRESET)
    }

    /// The preset of [`Scene::default_stereo_options`].
    pub const DEFAULT_STEREO_PRESET: stereo::Preset = stereo::Preset::Quality;

    /// Sets the stereo matcher's options, `max_disparity` included (it is checked against the
    /// image width when matching). Without this call the scene uses
    /// [`Scene::default_stereo_options`] with `max_disparity` from the calibration (`ndisp`) when
    /// it has one, else [`auto_max_disparity`] of the width.
    ///
    /// # Errors
    /// `InvalidArgument` for an option out of range; the scene is unchanged.
    pub fn set_stereo_options(&mut self, options: StereoOptions) -> Result<()> {
        let max_disparity = options.max_disparity;
        self.set_stereo_options_auto_range(options, Some(max_disparity))
    }

    /// Like [`Scene::set_stereo_options`], but with `max_disparity: None` the range is chosen as
    /// without options (calibration, else [`auto_max_disparity`]).
    ///
    /// # Errors
    /// `InvalidArgument` for an option out of range; the scene is unchanged.
    pub fn set_stereo_options_auto_range(
        &mut self,
        options: StereoOptions,
        max_disparity: Option<u32>,
    ) -> Result<()> {
        // u32::MAX stands for "any width": only the width-independent checks apply here.
        let mut checked = options.clone();
        checked.max_disparity = max_disparity.unwrap_or(1);
        checked.validate(u32::MAX)?;
        self.stereo_options.value = Some(StereoSettings {
            options,
            max_disparity,
        });
        self.stereo_options.version = self.bump();
        Ok(())
    }

    /// Back to the default stereo options.
    pub fn reset_stereo_options(&mut self) {
        self.stereo_options.value = None;
        self.stereo_options.version = self.bump();
    }

    /// Whether the disparity range comes from the scene's automatic choice (not the host).
    fn stereo_range_is_automatic(&self) -> bool {
        self.stereo_options
            .value
            .as_ref()
            .is_none_or(|s| s.max_disparity.is_none())
    }

    /// The options the next match uses (see [`Scene::set_stereo_options`]).
    pub fn effective_stereo_options(&self) -> StereoOptions {
        let settings = self.stereo_options.value.clone().unwrap_or_default();
        let width = self.photo_size().map(|(w, _)| w).unwrap_or(0);
        let max_disparity = settings.max_disparity.unwrap_or_else(|| {
            self.calibration
                .value
                .and_then(|c| c.max_disparity)
                .unwrap_or_else(|| auto_max_disparity(width))
        });
        StereoOptions {
            max_disparity,
            ..settings.options
        }
    }

    /// Size of the photo (the left view), if a stereo pair or a photo was given.
    pub fn photo_size(&self) -> Option<(u32, u32)> {
        self.stereo_pair
            .value
            .as_ref()
            .map(|p| (p.left.width(), p.left.height()))
    }

    /// The stereo pair decoded for the stages (product `stereo_pair`).
    ///
    /// # Errors
    /// `NotAvailable` when neither a stereo pair nor a photo was set.
    pub fn loaded_pair(&mut self) -> Result<Arc<LoadedPair>> {
        self.traced(|scene, trace| scene.loaded_pair_traced(trace))
    }

    fn loaded_pair_traced(&mut self, trace: &mut Trace) -> Result<Arc<LoadedPair>> {
        let Some(pair) = &self.stereo_pair.value else {
            return Err(Error::NotAvailable(
                "no photo: set a stereo pair (set_stereo_pair) or a photo (set_photo)".into(),
            ));
        };
        let versions = [self.stereo_pair.version];
        self.loaded_pair
            .get_or_compute("stereo_pair", &versions, trace, |trace| {
                let loaded = LoadedPair {
                    left_rgb: pair.left.to_linear_rgb(),
                    left_luma: pair.left.to_luma(),
                    right_luma: pair.right.as_ref().map(Image::to_luma),
                };
                if loaded.right_luma.as_ref() == Some(&loaded.left_luma) {
                    trace
                        .warn("the left and right images are identical: every disparity will be 0");
                }
                Ok(loaded)
            })
    }

    /// Runs one product request with a fresh trace, kept afterwards as [`Scene::last_trace`].
    fn traced<T>(&mut self, request: impl FnOnce(&mut Self, &mut Trace) -> Result<T>) -> Result<T> {
        let mut trace = Trace::new();
        trace.set_observer(self.observer.clone());
        let result = request(self, &mut trace);
        trace.finish();
        self.last_trace = trace;
        result
    }

    /// The disparity of the left view, with its confidence (product `stereo`).
    ///
    /// # Errors
    /// `NotAvailable` without a stereo pair (a photo alone has nothing to match);
    /// `InvalidArgument` when the options do not fit the images (e.g. `max_disparity` ≥ width).
    pub fn disparity(&mut self) -> Result<Arc<Disparity>> {
        self.traced(|scene, trace| scene.disparity_traced(trace))
    }

    fn disparity_traced(&mut self, trace: &mut Trace) -> Result<Arc<Disparity>> {
        let Some(pair) = &self.stereo_pair.value else {
            return Err(Error::NotAvailable(
                "no stereo pair: set one with set_stereo_pair".into(),
            ));
        };
        let Some(right) = &pair.right else {
            return Err(Error::NotAvailable(
                "only a photo was given (set_photo): stereo needs the right view; give the \
                 host's depth (set_depth) or a stereo pair (set_stereo_pair)"
                    .into(),
            ));
        };
        let options = self.effective_stereo_options();
        // Without explicit options the calibration's ndisp chooses the range, so it is an input.
        let versions = [
            self.stereo_pair.version,
            self.stereo_options.version,
            if self.stereo_range_is_automatic() {
                self.calibration.version
            } else {
                0
            },
        ];
        let disparity = self
            .disparity
            .get_or_compute("stereo", &versions, trace, |_| {
                stereo::match_pair(&pair.left.view(), &right.view(), &options)
            })?;
        trace.record_parts("stereo", &disparity.stats.timings);
        let textureless = disparity.stats.textureless_fraction;
        if textureless > MOSTLY_TEXTURELESS {
            trace.warn(format!(
                "stereo: {:.0} % of the pixels have nothing to match (no texture): their depth is \
                 a guess, with confidence 0",
                textureless * 100.0
            ));
        }
        Ok(disparity)
    }

    /// Depth of the left view in metres, NaN where unknown (product `depth`): the host's own depth
    /// when one was set ([`Scene::set_depth`]; stereo is then skipped), else
    /// `Z = f·B/(d + doffs)` from the stereo disparity. Without a calibration, stereo depth is up
    /// to scale ([`stereo::assumed_calibration`]) and the trace carries a warning.
    ///
    /// # Errors
    /// `NotAvailable` with neither a host depth map nor a stereo pair; else as
    /// [`Scene::disparity`].
    pub fn depth(&mut self) -> Result<Arc<Raster<f32>>> {
        self.traced(|scene, trace| scene.depth_traced(trace))
    }

    fn depth_traced(&mut self, trace: &mut Trace) -> Result<Arc<Raster<f32>>> {
        if let Some(host) = &self.host_depth.value {
            trace.record("stereo", StageStatus::Skipped, 0.0, "host depth given");
            // Tag 1 keeps these versions apart from the stereo path's (which start with 0).
            let versions = [1, self.host_depth.version];
            let depth = Arc::clone(&host.depth);
            return self
                .depth
                .get_or_share("depth", &versions, trace, |_| Ok(depth));
        }
        if self.stereo_pair.value.is_none() {
            return Err(Error::NotAvailable(
                "no depth: set a stereo pair (set_stereo_pair) or the host's depth (set_depth)"
                    .into(),
            ));
        }
        let disparity = self.disparity_traced(trace)?;
        let (width, height) = (
            disparity.disparity.width() as u32,
            disparity.disparity.height() as u32,
        );
        let calibration = match self.calibration.value {
            Some(c) => c,
            None => {
                trace.warn(format!(
                    "no calibration: depth is up to scale (assumed {}° horizontal field of view, baseline 1)",
                    stereo::ASSUMED_HORIZONTAL_FOV_DEG
                ));
                stereo::assumed_calibration(width, height)?
            }
        };
        let versions = [0, self.disparity.generation, self.calibration.version];
        self.depth.get_or_compute("depth", &versions, trace, |_| {
            stereo::depth_map(&disparity.disparity, &calibration)
        })
    }

    /// The trace of the last call that asked for a product.
    pub fn last_trace(&self) -> &Trace {
        &self.last_trace
    }

    /// Sends the progress, records and warnings of every later call to `observer` (`None` stops);
    /// its `progress` can cancel a call between products ([`crate::trace::TraceObserver`]).
    pub fn set_observer(&mut self, observer: Option<Observer>) {
        self.observer = observer;
    }
}

/// The disparity range searched when neither the host nor the calibration gives one: a quarter of
/// the width (at least 1, less than the width). That covers Middlebury-like scenes, whose nearest
/// objects sit at a disparity of 20–25 % of the width.
pub fn auto_max_disparity(width: u32) -> u32 {
    (width / 4).clamp(1, width.saturating_sub(1).max(1))
}

#[cfg(test)]
mod test_support;

#[cfg(test)]
mod tests {
    use super::test_support::shifted_pair;
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
        assert_eq!(Some(&third.left_luma), second.right_luma.as_ref());
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
    fn depth_follows_disparity_and_calibration_without_rematching() {
        let mut scene = scene_with(ImageLimits::default());
        let (l, r) = shifted_pair(96, 48, 6);
        scene.set_stereo_pair(&l.view(), &r.view()).unwrap();
        scene
            .set_stereo_options(StereoOptions {
                max_disparity: 16,
                ..Scene::default_stereo_options()
            })
            .unwrap();
        let disparity = scene.disparity().unwrap();
        assert_eq!(
            scene.last_trace().stage("stereo").unwrap().status,
            StageStatus::Computed
        );
        assert!(scene
            .last_trace()
            .stages()
            .iter()
            .any(|s| s.name.starts_with("stereo.")));
        // Away from the left border (no match there), the disparity is the shift.
        let d = *disparity.disparity.get(60, 24);
        assert!((d - 6.0).abs() < 0.25, "disparity {d}");

        // No calibration: depth up to scale, with a warning.
        let depth = scene.depth().unwrap();
        assert_eq!(
            scene.last_trace().stage("stereo").unwrap().status,
            StageStatus::Reused
        );
        assert_eq!(scene.last_trace().warnings().len(), 1);
        assert!(depth.get(60, 24).is_finite());

        // A calibration changes depth, not disparity: Z = f·B/d = 600·0.1/6 = 10 m.
        scene
            .set_calibration(StereoCalibration::from_focal_baseline(600.0, 0.1, 96, 48).unwrap())
            .unwrap();
        let depth = scene.depth().unwrap();
        assert_eq!(
            scene.last_trace().stage("stereo").unwrap().status,
            StageStatus::Reused
        );
        assert_eq!(
            scene.last_trace().stage("depth").unwrap().status,
            StageStatus::Computed
        );
        let z = *depth.get(60, 24);
        assert!((z - 10.0).abs() < 0.5, "depth {z}");
        assert!(scene.last_trace().warnings().is_empty());
    }

    #[test]
    fn calibration_ndisp_sets_the_range_unless_options_do() {
        let mut scene = scene_with(ImageLimits::default());
        let (l, r) = shifted_pair(96, 48, 6);
        scene.set_stereo_pair(&l.view(), &r.view()).unwrap();
        assert_eq!(
            scene.effective_stereo_options().max_disparity,
            auto_max_disparity(96)
        );
        let mut c = StereoCalibration::from_focal_baseline(600.0, 0.1, 96, 48).unwrap();
        c.max_disparity = Some(20);
        scene.set_calibration(c).unwrap();
        assert_eq!(scene.effective_stereo_options().max_disparity, 20);
        scene
            .set_stereo_options(StereoOptions {
                max_disparity: 12,
                ..Scene::default_stereo_options()
            })
            .unwrap();
        assert_eq!(scene.effective_stereo_options().max_disparity, 12);
        // A range that does not fit the image is an error when matching, naming the option.
        scene
            .set_stereo_options(StereoOptions {
                max_disparity: 200,
                ..Scene::default_stereo_options()
            })
            .unwrap();
        let err = scene.disparity().unwrap_err();
        assert!(err.to_string().contains("max_disparity"), "{err}");
        assert_eq!(auto_max_disparity(1), 1);
        assert_eq!(auto_max_disparity(3), 1);
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
