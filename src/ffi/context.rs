//! `plx_context`: options shared by scenes. Creating one never needs a GPU.

use std::ffi::{c_char, CStr};
use std::mem::{offset_of, size_of};
use std::sync::Arc;

use super::boundary::{guard, invalid, null_argument, CallError};
use super::handle::{Handle, Kind, GLOBAL_ERROR};
use crate::context::{Context, ContextOptions};
use crate::error::Status;
use crate::image::{ImageLimits, DEFAULT_MAX_PIXELS};

/// Opaque. Thread-safe: may be shared by scenes on several threads. Freed by `plx_context_free`;
/// scenes made from it keep what they need alive, so it may be freed before them.
pub struct plx_context {
    _private: [u8; 0],
}

pub(crate) type ContextHandle = Handle<Arc<Context>>;

/// Options of `plx_context_new`. Initialise with `plx_context_options_init`, then change fields:
/// new fields are only ever appended, and `size` tells the library which ones the caller knows.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct plx_context_options {
    /// `sizeof(plx_context_options)` as the caller compiled it.
    pub size: usize,
    /// Largest accepted image, in pixels (width × height). Default 64 Mi pixels.
    pub max_image_pixels: u64,
    /// NULL, or a NUL-terminated UTF-8 substring of the GPU adapter name to use (copied).
    /// NULL = the `WGPU_ADAPTER_NAME` environment variable, else the best adapter.
    pub adapter_name: *const c_char,
}

/// Fills `options` with the defaults and its `size`.
///
/// # Safety
/// `options` is NULL or points to a writable `plx_context_options`.
#[no_mangle]
pub unsafe extern "C" fn plx_context_options_init(options: *mut plx_context_options) -> Status {
    guard(&GLOBAL_ERROR, || {
        if options.is_null() {
            return Err(null_argument("options"));
        }
        *options = plx_context_options {
            size: size_of::<plx_context_options>(),
            max_image_pixels: DEFAULT_MAX_PIXELS,
            adapter_name: std::ptr::null(),
        };
        Ok(())
    })
}

/// Reads the fields the caller's struct version has; later fields keep their defaults.
unsafe fn read_options(options: *const plx_context_options) -> Result<ContextOptions, CallError> {
    let mut out = ContextOptions::default();
    if options.is_null() {
        return Ok(out);
    }
    // Read `size` alone first: an older caller's struct may be shorter than ours.
    let size = std::ptr::read(options.cast::<usize>());
    let has = |end: usize| size >= end;
    if !has(offset_of!(plx_context_options, size) + size_of::<usize>()) {
        return Err(invalid(format!(
            "options.size is {size}: set it with plx_context_options_init"
        )));
    }
    let base = options.cast::<u8>();
    if has(offset_of!(plx_context_options, max_image_pixels) + size_of::<u64>()) {
        let v = std::ptr::read_unaligned(
            base.add(offset_of!(plx_context_options, max_image_pixels))
                .cast::<u64>(),
        );
        if v == 0 {
            return Err(invalid("options.max_image_pixels must be > 0"));
        }
        out.limits = ImageLimits { max_pixels: v };
    }
    if has(offset_of!(plx_context_options, adapter_name) + size_of::<*const c_char>()) {
        let p = std::ptr::read_unaligned(
            base.add(offset_of!(plx_context_options, adapter_name))
                .cast::<*const c_char>(),
        );
        if !p.is_null() {
            let name = CStr::from_ptr(p)
                .to_str()
                .map_err(|_| invalid("options.adapter_name is not UTF-8"))?;
            out.adapter_name = Some(name.to_string());
        }
    }
    Ok(out)
}

/// Creates a context. `options` may be NULL for the defaults. Never opens the GPU: that happens
/// the first time a stage needs it. On failure the message is read with
/// `plx_last_error_message(NULL, …)`.
///
/// # Safety
/// `options` is NULL or a valid `plx_context_options` of at least `options->size` bytes;
/// `out` is writable.
#[no_mangle]
pub unsafe extern "C" fn plx_context_new(
    options: *const plx_context_options,
    out: *mut *mut plx_context,
) -> Status {
    guard(&GLOBAL_ERROR, || {
        if out.is_null() {
            return Err(null_argument("out"));
        }
        let options = read_options(options)?;
        let context = Context::new(options)?;
        *out = ContextHandle::into_raw(Kind::Context, Arc::new(context)).cast();
        Ok(())
    })
}

/// Frees a context (NULL allowed). Scenes made from it stay valid.
///
/// # Safety
/// `context` is NULL or a live context not used by another thread during the call.
#[no_mangle]
pub unsafe extern "C" fn plx_context_free(context: *mut plx_context) {
    let _ = std::panic::catch_unwind(|| ContextHandle::free(context.cast(), Kind::Context));
}
