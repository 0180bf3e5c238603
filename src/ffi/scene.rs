//! `plx_scene`: one photo's reconstruction and what is inserted into it.

use std::sync::Arc;

use super::boundary::{guard, null_argument};
use super::context::{plx_context, ContextHandle};
use super::handle::{Handle, Kind, GLOBAL_ERROR};
use super::image::{plx_image, view};
use crate::error::Status;
use crate::scene::Scene;

/// Opaque. Not thread-safe: call functions on one scene from one thread at a time (any thread).
/// Views it returns stay valid until the next call that changes the scene.
pub struct plx_scene {
    _private: [u8; 0],
}

pub(crate) type SceneHandle = Handle<SceneState>;

/// What a `plx_scene` handle holds: the scene, and C copies of products whose Rust layout C
/// cannot read, kept so that the pointers handed out stay valid until the scene changes.
#[derive(Debug)]
pub(crate) struct SceneState {
    pub scene: Scene,
    /// The surfaces as C structs, with the product they were converted from.
    pub c_surfaces: Option<(Arc<crate::mesh::Surfaces>, Vec<super::query::plx_surface>)>,
    /// The host's progress callback and the log bridge, installed as the scene's observer.
    pub hooks: Arc<super::progress::SceneHooks>,
}

impl SceneState {
    /// Boxes `scene` as a new C handle with its own hooks (the progress callback of `from`).
    fn into_handle(mut scene: Scene, from: Option<&SceneState>) -> *mut plx_scene {
        let hooks = super::progress::SceneHooks::new_observer(from.map(|s| &*s.hooks));
        scene.set_observer(Some(hooks.observer()));
        let state = SceneState {
            scene,
            c_surfaces: from.and_then(|s| s.c_surfaces.clone()),
            hooks: Arc::clone(&hooks),
        };
        let handle = SceneHandle::into_raw(Kind::Scene, state);
        hooks.set_tag(handle as usize);
        handle.cast()
    }
}

impl std::fmt::Debug for super::progress::SceneHooks {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("SceneHooks(..)")
    }
}

/// Creates an empty scene in `context`.
///
/// # Safety
/// `context` is a live context; `out` is writable.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_new(
    context: *const plx_context,
    out: *mut *mut plx_scene,
) -> Status {
    guard(&GLOBAL_ERROR, || {
        if out.is_null() {
            return Err(null_argument("out"));
        }
        let context = ContextHandle::from_ptr(context.cast(), Kind::Context, "context")?;
        *out = SceneState::into_handle(Scene::new(Arc::clone(&context.value)), None);
        Ok(())
    })
}

/// Creates a new scene that starts as a copy of `scene`: the same inputs, options, artefacts,
/// progress callback and context, and the same computed products (depth, mesh, surfaces, …),
/// shared rather than copied, so the copy answers without recomputing them. Use it to run several
/// compositions of one reconstruction (other artefacts, placements, lights) side by side or on
/// several threads. From then on the two scenes change independently; each is freed with
/// `plx_scene_free`, in any order. Cheap: no pixel or mesh data is copied. Errors:
/// `NULL_ARGUMENT`.
///
/// # Safety
/// `scene` is a live scene; `out` is writable.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_clone(
    scene: *mut plx_scene,
    out: *mut *mut plx_scene,
) -> Status {
    with_scene_state(scene, |state| {
        if out.is_null() {
            return Err(null_argument("out"));
        }
        *out = SceneState::into_handle(state.scene.clone(), Some(state));
        Ok(())
    })
}

/// Frees a scene (NULL allowed).
///
/// # Safety
/// `scene` is NULL or a live scene not used by another thread during the call.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_free(scene: *mut plx_scene) {
    let _ = std::panic::catch_unwind(|| SceneHandle::free(scene.cast(), Kind::Scene));
}

/// Borrows the scene handle, reporting a NULL or foreign pointer in the global error slot.
pub(crate) unsafe fn with_scene(
    scene: *mut plx_scene,
    body: impl FnOnce(&mut Scene) -> Result<(), super::boundary::CallError>,
) -> Status {
    with_scene_state(scene, |state| body(&mut state.scene))
}

/// [`with_scene`] with the whole handle state (for products kept in C layout).
pub(crate) unsafe fn with_scene_state(
    scene: *mut plx_scene,
    body: impl FnOnce(&mut SceneState) -> Result<(), super::boundary::CallError>,
) -> Status {
    let entered =
        match std::panic::catch_unwind(|| SceneHandle::enter(scene.cast(), Kind::Scene, "scene")) {
            Ok(Ok(entered)) => entered,
            Ok(Err((Some(header), e))) => return guard(&header.error, || Err(e)),
            Ok(Err((None, e))) => return guard(&GLOBAL_ERROR, || Err(e)),
            Err(_) => return Status::Panic,
        };
    let status = guard(&entered.header.error, || body(&mut *entered.value));
    drop(entered);
    status
}

/// Sets the rectified stereo pair (left and right views of equal size, any `plx_pixel_format`).
/// Both are copied in. Errors: `NULL_ARGUMENT`, `INVALID_ARGUMENT` (zero size, stride shorter than
/// a row, unknown format), `SIZE_MISMATCH` (views of different sizes), `TOO_LARGE` (over the
/// context's pixel cap). On error the scene is unchanged.
///
/// # Safety
/// `scene` is a live scene; `left` and `right` point to valid descriptors of readable memory.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_set_stereo_pair(
    scene: *mut plx_scene,
    left: *const plx_image,
    right: *const plx_image,
) -> Status {
    with_scene(scene, |scene| {
        let left = view(left, "left")?;
        let right = view(right, "right")?;
        scene.set_stereo_pair(&left, &right)?;
        Ok(())
    })
}

/// Sets the photo alone (any `plx_pixel_format`, copied in), for a host that gives its own depth
/// (`plx_scene_set_depth`: ARCore, a depth camera) and wants lights and composites on this photo.
/// Replaces a stereo pair; stereo matching then answers `NOT_AVAILABLE`. Errors:
/// `NULL_ARGUMENT`, `INVALID_ARGUMENT` (zero size, stride shorter than a row, unknown format),
/// `SIZE_MISMATCH` (a host depth map of another size), `TOO_LARGE` (over the context's pixel
/// cap). On error the scene is unchanged.
///
/// # Safety
/// `scene` is a live scene; `photo` points to a valid descriptor of readable memory.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_set_photo(
    scene: *mut plx_scene,
    photo: *const plx_image,
) -> Status {
    with_scene(scene, |scene| {
        let photo = view(photo, "photo")?;
        scene.set_photo(&photo)?;
        Ok(())
    })
}

#[cfg(feature = "test-hooks")]
pub(crate) unsafe fn with_scene_for_tests(scene: *mut plx_scene, body: impl FnOnce()) -> Status {
    with_scene(scene, |_| {
        body();
        Ok(())
    })
}

/// Calibration of a rectified pair, for `plx_scene_set_calibration`.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct plx_calibration {
    /// Focal length in pixels (> 0).
    pub focal_px: f64,
    /// Principal point of the left view, pixels from the left edge.
    pub cx: f64,
    /// Principal point of the left view, pixels from the top edge.
    pub cy: f64,
    /// Distance between the camera centres, metres (> 0).
    pub baseline_m: f64,
    /// x difference of the principal points, right minus left, pixels (Middlebury `doffs`).
    pub doffs: f64,
    /// Largest disparity worth searching, pixels; 0 = unknown.
    pub max_disparity: u32,
}

/// Sets the calibration of the stereo pair (used to turn disparity into metres). Errors:
/// `INVALID_ARGUMENT` for a non-finite or non-positive focal length or baseline, non-finite
/// offsets. On error the scene is unchanged.
///
/// # Safety
/// `scene` is a live scene; `calibration` points to a valid `plx_calibration`.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_set_calibration(
    scene: *mut plx_scene,
    calibration: *const plx_calibration,
) -> Status {
    with_scene(scene, |scene| {
        if calibration.is_null() {
            return Err(null_argument("calibration"));
        }
        let c = &*calibration;
        scene.set_calibration(crate::camera::StereoCalibration {
            focal_px: c.focal_px,
            cx: c.cx,
            cy: c.cy,
            baseline_m: c.baseline_m,
            doffs: c.doffs,
            max_disparity: (c.max_disparity > 0).then_some(c.max_disparity),
        })?;
        Ok(())
    })
}

/// Copies the JSON report of the scene's last call that computed or fetched a product (stages
/// computed, reused or skipped with their times, warnings, peak memory; the format is documented
/// in the README) into `buf`, like `plx_last_error_message`: truncated to `len - 1` bytes plus a
/// NUL, with the full size including the NUL in `*needed` (if not NULL).
///
/// # Safety
/// `scene` is a live scene; `buf` points to `len` writable bytes (may be NULL when `len` is 0).
#[no_mangle]
pub unsafe extern "C" fn plx_scene_report(
    scene: *mut plx_scene,
    buf: *mut std::ffi::c_char,
    len: usize,
    needed: *mut usize,
) -> Status {
    with_scene(scene, |scene| {
        if buf.is_null() && len > 0 {
            return Err(null_argument("buf"));
        }
        let json = scene.last_trace().report().to_json();
        super::status::copy_c_string(&json, buf, len, needed);
        Ok(())
    })
}
