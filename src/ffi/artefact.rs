//! Artefacts (glTF objects inserted into the photo) through the C ABI: add from a file or from
//! memory, move, show/hide, shadow flags, remove, bounds, placement and loader warnings.
//!
//! Built without the `gltf` feature, every function here returns `PLX_STATUS_UNSUPPORTED`.

use super::boundary::{null_argument, CallError};
use super::scene::{plx_scene, with_scene};
use crate::error::Status;

#[cfg(feature = "gltf")]
use super::boundary::invalid;
#[cfg(feature = "gltf")]
use crate::artefact::ArtefactId;
#[cfg(feature = "gltf")]
use glam::{Mat4, Vec2};

/// The error of every artefact function in a build without glTF support.
#[cfg(not(feature = "gltf"))]
fn no_gltf() -> CallError {
    CallError {
        status: Status::Unsupported,
        message: "this build of Parallax has no glTF support (cargo feature \"gltf\")".into(),
    }
}

/// Reads a column-major 4×4 matrix; NULL gives `null` (identity, or an error for the caller).
#[cfg(feature = "gltf")]
unsafe fn read_matrix(m: *const f32) -> Option<Mat4> {
    if m.is_null() {
        return None;
    }
    let mut cols = [0.0f32; 16];
    std::ptr::copy_nonoverlapping(m, cols.as_mut_ptr(), 16);
    Some(Mat4::from_cols_array(&cols))
}

/// The C id of a new artefact. Ids count up from 0 and are never reused; past `u32::MAX` adds
/// the scene cannot hand out more (the artefact just added is removed again).
#[cfg(feature = "gltf")]
fn c_id(scene: &mut crate::scene::Scene, id: ArtefactId) -> Result<u32, CallError> {
    match u32::try_from(id.0) {
        Ok(v) => Ok(v),
        Err(_) => {
            scene.remove_artefact(id)?;
            Err(CallError {
                status: Status::TooLarge,
                message: "artefact ids exhausted: this scene has handed out 2^32 ids".into(),
            })
        }
    }
}

#[cfg(feature = "gltf")]
fn flag(value: u32, name: &str) -> Result<bool, CallError> {
    match value {
        0 => Ok(false),
        1 => Ok(true),
        other => Err(invalid(format!("{name} must be 0 or 1, got {other}"))),
    }
}

/// Loads a glTF 2.0 file (`.gltf` with external or embedded buffers, or `.glb`) and places it in
/// the scene with `transform` (16 floats, column-major, asset space → world, metres; NULL =
/// identity): visible, casting and receiving shadows. External buffers and images are read only
/// from the file's folder and below. A file this scene already loaded and that is unchanged on
/// disk is not read again: the new artefact shares its data. The new id goes to `*out_id`.
/// The loader's warnings: `plx_scene_artefact_warnings`, and the report (`plx_scene_report`).
///
/// Errors: `NULL_ARGUMENT`; `INVALID_ARGUMENT` (non-finite transform, a URI outside the asset's
/// folder); `IO` (the file, or a buffer or image it names, cannot be read); `FORMAT` (malformed
/// file: the message names the accessor, index, node or URI); `UNSUPPORTED` (a required extension
/// such as Draco; a build without glTF support); `TOO_LARGE` (over the load caps). On error the
/// scene is unchanged.
///
/// # Safety
/// `scene` is a live scene; `path` is a NUL-terminated string; `transform` is NULL or points to 16
/// readable floats; `out_id` is writable.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_add_artefact_path(
    scene: *mut plx_scene,
    path: *const std::ffi::c_char,
    transform: *const f32,
    out_id: *mut u32,
) -> Status {
    with_scene(scene, |scene| {
        if path.is_null() {
            return Err(null_argument("path"));
        }
        if out_id.is_null() {
            return Err(null_argument("out_id"));
        }
        #[cfg(feature = "gltf")]
        {
            let bytes = std::ffi::CStr::from_ptr(path).to_bytes();
            #[cfg(unix)]
            let path = std::path::PathBuf::from(
                <std::ffi::OsStr as std::os::unix::ffi::OsStrExt>::from_bytes(bytes),
            );
            #[cfg(not(unix))]
            let path = std::path::PathBuf::from(
                std::str::from_utf8(bytes).map_err(|_| invalid("path is not valid UTF-8"))?,
            );
            let transform = read_matrix(transform).unwrap_or(Mat4::IDENTITY);
            let id = scene.add_artefact_path(&path, transform)?;
            *out_id = c_id(scene, id)?;
            Ok(())
        }
        #[cfg(not(feature = "gltf"))]
        {
            let _ = (scene, transform);
            Err(no_gltf())
        }
    })
}

/// Loads a GLB, or `.gltf` JSON whose buffers and images are all embedded (`data:` URIs), from
/// `len` bytes of memory (copied as needed; the caller may free them afterwards) and places it
/// like `plx_scene_add_artefact_path`. A URI naming an external file is refused
/// (`INVALID_ARGUMENT`). Other errors as `plx_scene_add_artefact_path`. On error the scene is
/// unchanged.
///
/// # Safety
/// `scene` is a live scene; `bytes` points to `len` readable bytes (may be NULL when `len` is 0);
/// `transform` is NULL or points to 16 readable floats; `out_id` is writable.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_add_artefact_memory(
    scene: *mut plx_scene,
    bytes: *const u8,
    len: usize,
    transform: *const f32,
    out_id: *mut u32,
) -> Status {
    with_scene(scene, |scene| {
        if bytes.is_null() && len > 0 {
            return Err(null_argument("bytes"));
        }
        if out_id.is_null() {
            return Err(null_argument("out_id"));
        }
        #[cfg(feature = "gltf")]
        {
            let data: &[u8] = if len == 0 {
                &[]
            } else {
                std::slice::from_raw_parts(bytes, len)
            };
            let transform = read_matrix(transform).unwrap_or(Mat4::IDENTITY);
            let id = scene.add_artefact_bytes(data, transform)?;
            *out_id = c_id(scene, id)?;
            Ok(())
        }
        #[cfg(not(feature = "gltf"))]
        {
            let _ = (scene, transform);
            Err(no_gltf())
        }
    })
}

/// Moves artefact `id`: `transform` is 16 floats, column-major, asset space → world, metres.
/// Depth, mesh and surfaces are not recomputed for it. Errors: `NULL_ARGUMENT`;
/// `INVALID_ARGUMENT` (unknown id, non-finite transform). On error nothing changes.
///
/// # Safety
/// `scene` is a live scene; `transform` points to 16 readable floats.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_set_artefact_transform(
    scene: *mut plx_scene,
    id: u32,
    transform: *const f32,
) -> Status {
    with_scene(scene, |scene| {
        if transform.is_null() {
            return Err(null_argument("transform"));
        }
        #[cfg(feature = "gltf")]
        {
            let m = read_matrix(transform).unwrap_or(Mat4::IDENTITY);
            scene.set_artefact_transform(ArtefactId(id as u64), m)?;
            Ok(())
        }
        #[cfg(not(feature = "gltf"))]
        {
            let _ = (scene, id);
            Err(no_gltf())
        }
    })
}

/// Sets artefact `id`'s flags, each 0 or 1: `visible` (drawn at all), `casts_shadow` (darkens the
/// photo and other artefacts), `receives_shadow` (darkened by other artefacts). New artefacts
/// have all three set. Errors: `INVALID_ARGUMENT` (unknown id, a flag other than 0 or 1). On
/// error nothing changes.
///
/// # Safety
/// `scene` is a live scene.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_set_artefact_flags(
    scene: *mut plx_scene,
    id: u32,
    visible: u32,
    casts_shadow: u32,
    receives_shadow: u32,
) -> Status {
    with_scene(scene, |scene| {
        #[cfg(feature = "gltf")]
        {
            let visible = flag(visible, "visible")?;
            let casts = flag(casts_shadow, "casts_shadow")?;
            let receives = flag(receives_shadow, "receives_shadow")?;
            let id = ArtefactId(id as u64);
            // Checked first so that an unknown id changes nothing.
            scene.artefact_bounds(id)?;
            scene.set_artefact_visible(id, visible)?;
            scene.set_artefact_shadows(id, casts, receives)?;
            Ok(())
        }
        #[cfg(not(feature = "gltf"))]
        {
            let _ = (scene, id, visible, casts_shadow, receives_shadow);
            Err(no_gltf())
        }
    })
}

/// Removes artefact `id` (its data is freed once no other artefact shares it). Ids are never
/// reused. Errors: `INVALID_ARGUMENT` for an unknown or already removed id.
///
/// # Safety
/// `scene` is a live scene.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_remove_artefact(scene: *mut plx_scene, id: u32) -> Status {
    with_scene(scene, |scene| {
        #[cfg(feature = "gltf")]
        {
            scene.remove_artefact(ArtefactId(id as u64))?;
            Ok(())
        }
        #[cfg(not(feature = "gltf"))]
        {
            let _ = (scene, id);
            Err(no_gltf())
        }
    })
}

/// Bounding boxes of artefact `id`, metres: in its own asset space (`local_min`, `local_max`) and
/// in the world after its transform (`world_min`, `world_max`: the box holding the eight
/// transformed corners). Each output is 3 floats (x, y, z); any may be NULL when not wanted. An
/// artefact without geometry has the empty box at its origin. Errors: `INVALID_ARGUMENT` for an
/// unknown id.
///
/// # Safety
/// `scene` is a live scene; each output is NULL or points to 3 writable floats.
#[no_mangle]
pub unsafe extern "C" fn plx_artefact_bounds(
    scene: *mut plx_scene,
    id: u32,
    local_min: *mut f32,
    local_max: *mut f32,
    world_min: *mut f32,
    world_max: *mut f32,
) -> Status {
    with_scene(scene, |scene| {
        #[cfg(feature = "gltf")]
        {
            let b = scene.artefact_bounds(ArtefactId(id as u64))?;
            for (out, v) in [
                (local_min, b.local.min),
                (local_max, b.local.max),
                (world_min, b.world.min),
                (world_max, b.world.max),
            ] {
                if !out.is_null() {
                    std::ptr::copy_nonoverlapping(v.to_array().as_ptr(), out, 3);
                }
            }
            Ok(())
        }
        #[cfg(not(feature = "gltf"))]
        {
            let _ = (scene, id, local_min, local_max, world_min, world_max);
            Err(no_gltf())
        }
    })
}

/// Stands artefact `id` on the scene surface seen at image position (`x`, `y`) (continuous
/// pixels, like `plx_scene_place`) at its real size: the bottom centre of its bounding box on the
/// surface, its largest side `size_m` metres, turned by `yaw_deg` degrees about the up axis. Sets
/// the artefact's transform and, when `out_transform` is not NULL, writes it there (16 floats,
/// column-major). Needs depth (computed if needed). Errors: `NOT_AVAILABLE` without depth;
/// `INVALID_ARGUMENT` (unknown id, an artefact without geometry, a pixel with no surface, a size
/// that is not finite and > 0, a non-finite yaw). On error the transform is unchanged. The
/// estimated lighting is built around `plx_scene_set_insertion_point`'s point, not around the
/// artefacts: pass the placed translation (`out_transform[12..15]`) there so that the object is
/// lit and reflects the room from where it stands.
///
/// # Safety
/// `scene` is a live scene; `out_transform` is NULL or points to 16 writable floats.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_place_artefact(
    scene: *mut plx_scene,
    id: u32,
    x: f32,
    y: f32,
    size_m: f32,
    yaw_deg: f32,
    out_transform: *mut f32,
) -> Status {
    with_scene(scene, |scene| {
        #[cfg(feature = "gltf")]
        {
            let placement = scene.place_artefact(
                ArtefactId(id as u64),
                Vec2::new(x, y),
                size_m,
                yaw_deg.to_radians(),
            )?;
            if !out_transform.is_null() {
                let cols = placement.transform.to_cols_array();
                std::ptr::copy_nonoverlapping(cols.as_ptr(), out_transform, 16);
            }
            Ok(())
        }
        #[cfg(not(feature = "gltf"))]
        {
            let _ = (scene, id, x, y, size_m, yaw_deg, out_transform);
            Err(no_gltf())
        }
    })
}

/// The warnings the loader raised for artefact `id` (what it repaired or ignored: generated
/// normals, an unsupported optional extension, skipped points and lines, …), one per line,
/// copied into `buf` like `plx_last_error_message` (truncated to `len - 1` bytes plus a NUL; the
/// full size including the NUL in `*needed` when not NULL). `*count` (when not NULL) receives the
/// number of warnings; "" and 0 when there are none. Errors: `NULL_ARGUMENT` (`buf` NULL with
/// `len > 0`); `INVALID_ARGUMENT` for an unknown id.
///
/// # Safety
/// `scene` is a live scene; `buf` points to `len` writable bytes (may be NULL when `len` is 0);
/// `needed` and `count` are NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_artefact_warnings(
    scene: *mut plx_scene,
    id: u32,
    buf: *mut std::ffi::c_char,
    len: usize,
    needed: *mut usize,
    count: *mut usize,
) -> Status {
    with_scene(scene, |scene| {
        if buf.is_null() && len > 0 {
            return Err(null_argument("buf"));
        }
        #[cfg(feature = "gltf")]
        {
            let id = ArtefactId(id as u64);
            let instance = scene
                .artefacts()
                .get(id)
                .ok_or_else(|| invalid(format!("no artefact with id {}", id.0)))?;
            let warnings = &instance.artefact.warnings;
            super::status::copy_c_string(&warnings.join("\n"), buf, len, needed);
            if !count.is_null() {
                *count = warnings.len();
            }
            Ok(())
        }
        #[cfg(not(feature = "gltf"))]
        {
            let _ = (scene, id, needed, count);
            Err(no_gltf())
        }
    })
}
