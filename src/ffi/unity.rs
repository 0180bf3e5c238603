//! Unity native rendering-plugin entry points (feature `unity`).
//!
//! Unity loads a native plugin, calls `UnityPluginLoad` with its interface table, and later runs
//! the plugin's callback on its render thread for each `CommandBuffer.IssuePluginEvent` /
//! `GL.IssuePluginEvent(GetRenderEventFunc(), eventId)`. Parallax renders on its own wgpu device
//! and writes the composite into a CPU buffer; it does not use Unity's graphics interfaces, so the
//! table is only kept (`plx_unity_interfaces_get`). The host registers beforehand what each event
//! id renders (`plx_unity_set_render_target`) and reads the outcome afterwards
//! (`plx_unity_last_event_status`, `plx_unity_last_event_message`), then uploads the buffer into
//! its texture (e.g. `Texture2D.LoadRawTextureData` + `Apply`).
//!
//! Calling convention: Unity's `UNITY_INTERFACE_API` is `__stdcall` only on 32-bit Windows, which
//! Parallax does not support; everywhere else it is the C convention used here.

#![allow(non_snake_case)]

use std::collections::HashMap;
use std::ffi::{c_char, c_void};
use std::mem::size_of;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Mutex;

use super::boundary::{guard, invalid, null_argument, CallError};
use super::handle::{error_slot_of, HandleHeader, GLOBAL_ERROR};
use super::image_io::plx_image_out;
use super::render::{plx_render_options, plx_render_options_init, plx_scene_render};
use super::scene::plx_scene;
use crate::error::Status;

/// A Unity interface GUID (Unity's `UnityInterfaceGUID`: two 64-bit halves).
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct plx_unity_guid {
    /// `m_GUIDHigh`.
    pub high: u64,
    /// `m_GUIDLow`.
    pub low: u64,
}

/// The layout of Unity's `IUnityInterfaces` (`IUnityInterface.h`): the table Unity passes to
/// `UnityPluginLoad`. Parallax keeps the pointer and calls none of its functions.
#[repr(C)]
pub struct plx_unity_interfaces {
    /// `GetInterface(guid)`: the interface registered under `guid`, or NULL.
    pub GetInterface: Option<unsafe extern "C" fn(guid: plx_unity_guid) -> *mut c_void>,
    /// `RegisterInterface(guid, ptr)`.
    pub RegisterInterface: Option<unsafe extern "C" fn(guid: plx_unity_guid, ptr: *mut c_void)>,
    /// `GetInterfaceSplit(high, low)`: `GetInterface` with the GUID in two arguments.
    pub GetInterfaceSplit: Option<unsafe extern "C" fn(high: u64, low: u64) -> *mut c_void>,
    /// `RegisterInterfaceSplit(high, low, ptr)`.
    pub RegisterInterfaceSplit: Option<unsafe extern "C" fn(high: u64, low: u64, ptr: *mut c_void)>,
}

/// Unity's `UnityRenderingEvent`: the callback `GetRenderEventFunc` returns, run by Unity on its
/// render thread with the event id given to `IssuePluginEvent`.
pub type plx_unity_rendering_event = Option<unsafe extern "C" fn(event_id: i32)>;

/// What one event id renders (raw pointers kept as addresses: the host guarantees their life).
#[derive(Clone, Copy)]
struct Target {
    scene: usize,
    options: plx_render_options,
    out: plx_image_out,
    mask: Option<plx_image_out>,
}

/// The outcome of an event id's last run.
#[derive(Default, Clone)]
struct Outcome {
    status: Option<Status>,
    message: String,
    runs: u64,
}

#[derive(Default)]
struct Plugin {
    interfaces: usize,
    targets: HashMap<i32, Target>,
    outcomes: HashMap<i32, Outcome>,
}

// SAFETY of the raw addresses inside: the table only stores them; they are dereferenced by the
// render event under the host's guarantee (documented at `plx_unity_set_render_target`).
unsafe impl Send for Target {}

static PLUGIN: Mutex<Option<Plugin>> = Mutex::new(None);

fn with_plugin<R>(f: impl FnOnce(&mut Plugin) -> R) -> R {
    // A poisoned lock only means a panic elsewhere while holding it; the table is still valid.
    let mut lock = PLUGIN.lock().unwrap_or_else(|p| p.into_inner());
    f(lock.get_or_insert_with(Plugin::default))
}

/// Called by Unity when it loads the plugin, with its interface table (kept, see
/// `plx_unity_interfaces_get`; Parallax needs none of Unity's graphics interfaces). Never fails.
///
/// # Safety
/// `interfaces` is NULL or Unity's table, valid until `UnityPluginUnload`.
#[no_mangle]
pub unsafe extern "C" fn UnityPluginLoad(interfaces: *mut plx_unity_interfaces) {
    let _ = catch_unwind(|| {
        with_plugin(|p| p.interfaces = interfaces as usize);
        super::log::log(
            super::log::plx_log_level::Info,
            "Unity plugin loaded: rendering into CPU buffers on Parallax's own GPU device",
        );
    });
}

/// Called by Unity before it unloads the plugin: forgets the interface table, every render target
/// and every recorded event outcome. Scenes and buffers stay the host's to free.
#[no_mangle]
pub extern "C" fn UnityPluginUnload() {
    let _ = catch_unwind(|| {
        with_plugin(|p| *p = Plugin::default());
    });
}

/// The render-event callback for Unity's `IssuePluginEvent(GetRenderEventFunc(), eventId)`:
/// renders the target registered for `eventId` (`plx_unity_set_render_target`) on the calling
/// (render) thread and records the outcome (`plx_unity_last_event_status`). Never NULL.
#[no_mangle]
pub extern "C" fn GetRenderEventFunc() -> plx_unity_rendering_event {
    Some(on_render_event)
}

unsafe extern "C" fn on_render_event(event_id: i32) {
    let outcome = catch_unwind(AssertUnwindSafe(|| run_event(event_id))).unwrap_or_else(|_| {
        (
            Status::Panic,
            format!("internal panic while running render event {event_id}"),
        )
    });
    let _ = catch_unwind(AssertUnwindSafe(|| {
        if outcome.0 != Status::Ok {
            super::log::log(
                super::log::plx_log_level::Error,
                &format!("Unity render event {event_id}: {}", outcome.1),
            );
        }
        with_plugin(|p| {
            let o = p.outcomes.entry(event_id).or_default();
            o.status = Some(outcome.0);
            o.message = outcome.1;
            o.runs += 1;
        });
    }));
}

/// Renders event `event_id`'s target; the status and message to record.
unsafe fn run_event(event_id: i32) -> (Status, String) {
    // Copy the target out so the table's lock is not held while rendering.
    let Some(target) = with_plugin(|p| p.targets.get(&event_id).copied()) else {
        return (
            Status::InvalidArgument,
            format!("no render target registered for event id {event_id}"),
        );
    };
    let scene = target.scene as *mut plx_scene;
    let mask = target
        .mask
        .as_ref()
        .map_or(std::ptr::null(), |m| m as *const _);
    let status = plx_scene_render(scene, &target.options, &target.out, mask);
    let message = if status == Status::Ok {
        String::new()
    } else {
        error_slot_of(scene as *const HandleHeader)
            .map(|slot| slot.get())
            .unwrap_or_default()
    };
    (status, message)
}

/// Registers what Unity's render event `event_id` renders: the composite of `scene` with
/// `options` (NULL = defaults; copied) into `out` and, when `mask_out` is not NULL, the coverage
/// into it (both descriptors copied; the pixels they point to are written by each event run, as
/// `plx_scene_render` writes them). Replaces an earlier target of that id; `scene` NULL removes
/// it. The scene and the buffers must stay alive until the target is replaced or removed, or the
/// plugin unloaded; while an event runs the scene is busy (another call on it fails with
/// `INVALID_ARGUMENT`, "busy", and so would the event while the host uses the scene: its outcome
/// says so). Thread-safe. Errors: `NULL_ARGUMENT` (`out`, or `out->data`, with a scene);
/// `INVALID_ARGUMENT` (`options->size` too small). On error nothing changes.
///
/// # Safety
/// `scene` is NULL or a live scene; `options` is NULL or valid for `options->size` bytes; `out`
/// and `mask_out` are NULL or valid `plx_image_out`s, their memory as stated above.
#[no_mangle]
pub unsafe extern "C" fn plx_unity_set_render_target(
    event_id: i32,
    scene: *mut plx_scene,
    options: *const plx_render_options,
    out: *const plx_image_out,
    mask_out: *const plx_image_out,
) -> Status {
    guard(&GLOBAL_ERROR, || {
        if scene.is_null() {
            with_plugin(|p| p.targets.remove(&event_id));
            return Ok(());
        }
        if out.is_null() {
            return Err(null_argument("out"));
        }
        if (*out).data.is_null() {
            return Err(null_argument("out.data"));
        }
        let options = copy_options(options)?;
        let target = Target {
            scene: scene as usize,
            options,
            out: *out,
            mask: (!mask_out.is_null()).then(|| *mask_out),
        };
        with_plugin(|p| p.targets.insert(event_id, target));
        Ok(())
    })
}

/// The caller's options over the defaults, `size` bytes of them (an older, shorter struct keeps
/// the defaults of the fields it lacks).
unsafe fn copy_options(
    options: *const plx_render_options,
) -> Result<plx_render_options, CallError> {
    let mut copy = std::mem::MaybeUninit::<plx_render_options>::zeroed();
    if plx_render_options_init(copy.as_mut_ptr()) != Status::Ok {
        return Err(CallError {
            status: Status::Internal,
            message: "plx_render_options_init failed".into(),
        });
    }
    let mut copy = copy.assume_init();
    if options.is_null() {
        return Ok(copy);
    }
    let size = std::ptr::read_unaligned(options.cast::<usize>());
    if size < size_of::<usize>() {
        return Err(invalid(format!(
            "options.size is {size}: set it with plx_render_options_init"
        )));
    }
    let n = size.min(size_of::<plx_render_options>());
    std::ptr::copy_nonoverlapping(
        options.cast::<u8>(),
        (&mut copy as *mut plx_render_options).cast::<u8>(),
        n,
    );
    copy.size = size_of::<plx_render_options>();
    Ok(copy)
}

/// The status the last run of render event `event_id` returned (what `plx_scene_render` returned
/// for its target; `INVALID_ARGUMENT` when no target was registered for it; `PANIC` when one was
/// caught), and into `*runs` (when not NULL) how many times it ran since the plugin was loaded.
/// An id that never ran gives `NOT_AVAILABLE` and 0 runs. Thread-safe.
///
/// # Safety
/// `runs` is NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn plx_unity_last_event_status(event_id: i32, runs: *mut u64) -> Status {
    catch_unwind(|| {
        let o = with_plugin(|p| p.outcomes.get(&event_id).cloned().unwrap_or_default());
        if !runs.is_null() {
            *runs = o.runs;
        }
        o.status.unwrap_or(Status::NotAvailable)
    })
    .unwrap_or(Status::Panic)
}

/// Copies the message of the last run of render event `event_id` ("" after a success or when it
/// never ran) into `buf`, like `plx_last_error_message` (truncated to `len - 1` bytes plus a NUL,
/// the full size including the NUL in `*needed` when not NULL). Thread-safe. Errors:
/// `NULL_ARGUMENT` (`buf` NULL with `len > 0`).
///
/// # Safety
/// `buf` points to `len` writable bytes (may be NULL when `len` is 0); `needed` is NULL or
/// writable.
#[no_mangle]
pub unsafe extern "C" fn plx_unity_last_event_message(
    event_id: i32,
    buf: *mut c_char,
    len: usize,
    needed: *mut usize,
) -> Status {
    guard(&GLOBAL_ERROR, || {
        if buf.is_null() && len > 0 {
            return Err(null_argument("buf"));
        }
        let message = with_plugin(|p| {
            p.outcomes
                .get(&event_id)
                .map(|o| o.message.clone())
                .unwrap_or_default()
        });
        super::status::copy_c_string(&message, buf, len, needed);
        Ok(())
    })
}

/// The interface table Unity gave `UnityPluginLoad`, or NULL before it / after
/// `UnityPluginUnload`. Thread-safe.
#[no_mangle]
pub extern "C" fn plx_unity_interfaces_get() -> *const plx_unity_interfaces {
    catch_unwind(|| with_plugin(|p| p.interfaces as *const plx_unity_interfaces))
        .unwrap_or(std::ptr::null())
}

#[cfg(all(test, feature = "gpu", feature = "gltf"))]
mod tests {
    use super::*;
    use crate::ffi::artefact::plx_scene_add_artefact_memory;
    use crate::ffi::context::{plx_context, plx_context_free, plx_context_new};
    use crate::ffi::image::plx_image;
    use crate::ffi::scene::{
        plx_calibration, plx_scene_free, plx_scene_new, plx_scene_set_calibration,
        plx_scene_set_stereo_pair,
    };

    /// A textured wall 1 m away (disparity 6 px at f = 60 px, B = 0.1 m), as a grey stereo pair.
    fn wall(w: u32, h: u32) -> (Vec<u8>, Vec<u8>) {
        let texture = |x: i64, y: i64| -> u8 {
            let mut v = (x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663)) as u64;
            v ^= v >> 13;
            v = v.wrapping_mul(0x5bd1_e995);
            (v >> 24) as u8
        };
        let make = |offset: i64| -> Vec<u8> {
            (0..h as i64)
                .flat_map(|y| (0..w as i64).map(move |x| texture(x + offset, y)))
                .collect()
        };
        (make(0), make(6))
    }

    /// Unity's render thread runs the event of a scene with a box in it: the composite and the
    /// mask land in the host's buffers through the GPU renderer.
    #[test]
    fn render_event_draws_an_artefact_into_the_hosts_buffer_on_another_thread() {
        const W: u32 = 96;
        const H: u32 = 48;
        unsafe {
            let mut ctx: *mut plx_context = std::ptr::null_mut();
            assert_eq!(plx_context_new(std::ptr::null(), &mut ctx), Status::Ok);
            let mut scene: *mut plx_scene = std::ptr::null_mut();
            assert_eq!(plx_scene_new(ctx, &mut scene), Status::Ok);
            let (l, r) = wall(W, H);
            let image = |data: &[u8]| plx_image {
                data: data.as_ptr(),
                width: W,
                height: H,
                stride: W as usize,
                format: crate::ffi::image::plx_pixel_format::Gray8 as u32,
            };
            assert_eq!(
                plx_scene_set_stereo_pair(scene, &image(&l), &image(&r)),
                Status::Ok
            );
            let calibration = plx_calibration {
                focal_px: 60.0,
                cx: W as f64 / 2.0,
                cy: H as f64 / 2.0,
                baseline_m: 0.1,
                doffs: 0.0,
                max_disparity: 16,
            };
            assert_eq!(plx_scene_set_calibration(scene, &calibration), Status::Ok);
            // A 0.2 m box 0.6 m in front of the camera, covering the centre.
            let glb = crate::artefact::builtin_glb("box").unwrap();
            let transform =
                glam::Mat4::from_translation(glam::Vec3::new(0.0, -0.1, -0.6)).to_cols_array();
            let mut id = 0;
            assert_eq!(
                plx_scene_add_artefact_memory(
                    scene,
                    glb.as_ptr(),
                    glb.len(),
                    transform.as_ptr(),
                    &mut id
                ),
                Status::Ok
            );

            let mut rgba = vec![0u8; (W * H * 4) as usize];
            let mut mask = vec![0u8; (W * H) as usize];
            let out = plx_image_out {
                data: rgba.as_mut_ptr(),
                width: W,
                height: H,
                stride: W as usize * 4,
                format: crate::ffi::image::plx_pixel_format::Rgba8 as u32,
            };
            let mask_out = plx_image_out {
                data: mask.as_mut_ptr(),
                width: W,
                height: H,
                stride: W as usize,
                format: crate::ffi::image::plx_pixel_format::Gray8 as u32,
            };
            UnityPluginLoad(std::ptr::null_mut());
            assert_eq!(
                plx_unity_set_render_target(11, scene, std::ptr::null(), &out, &mask_out),
                Status::Ok
            );
            let event = GetRenderEventFunc().unwrap();
            std::thread::spawn(move || event(11)).join().unwrap();
            let mut runs = 0;
            let status = plx_unity_last_event_status(11, &mut runs);
            let mut msg = [0 as c_char; 256];
            plx_unity_last_event_message(11, msg.as_mut_ptr(), msg.len(), std::ptr::null_mut());
            let msg = std::ffi::CStr::from_ptr(msg.as_ptr()).to_string_lossy();
            assert_eq!((status, runs), (Status::Ok, 1), "{msg}");
            UnityPluginUnload();

            let centre = ((H / 2) * W + W / 2) as usize;
            assert_eq!(mask[centre], 255, "the box covers the centre");
            assert_eq!(mask[0], 0, "and not the corner");
            // The blue box, not the grey wall texture, at the centre; opaque everywhere.
            let px = &rgba[centre * 4..centre * 4 + 4];
            assert!(px[2] > px[0] + 10, "centre {px:?}");
            assert!(rgba.chunks_exact(4).all(|p| p[3] == 255));

            plx_scene_free(scene);
            plx_context_free(ctx);
        }
    }
}
