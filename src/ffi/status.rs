//! Status strings, versions and error messages.

use std::ffi::{c_char, c_void};

use super::boundary::{guard, null_argument};
use super::handle::{error_slot_of, HandleHeader, GLOBAL_ERROR};
use crate::error::Status;

/// A static, NUL-terminated description of `status` (never NULL; unknown values give
/// "unknown status"). Thread-safe.
#[no_mangle]
pub extern "C" fn plx_status_str(status: u32) -> *const c_char {
    let text: &'static [u8] = match status_from_u32(status) {
        Some(Status::Ok) => b"ok\0",
        Some(Status::NullArgument) => b"a required pointer argument was NULL\0",
        Some(Status::InvalidArgument) => b"invalid argument\0",
        Some(Status::SizeMismatch) => b"size mismatch\0",
        Some(Status::TooLarge) => b"input too large\0",
        Some(Status::Format) => b"malformed data or unknown format\0",
        Some(Status::Io) => b"file input/output error\0",
        Some(Status::Unsupported) => b"unsupported\0",
        Some(Status::Gpu) => b"GPU error\0",
        Some(Status::NotAvailable) => b"not available: a required input is missing\0",
        Some(Status::Panic) => b"internal panic caught at the C boundary\0",
        Some(Status::Internal) => b"internal error\0",
        Some(Status::Cancelled) => b"cancelled by the host\0",
        None => b"unknown status\0",
    };
    text.as_ptr().cast()
}

fn status_from_u32(v: u32) -> Option<Status> {
    use Status::*;
    [
        Ok,
        NullArgument,
        InvalidArgument,
        SizeMismatch,
        TooLarge,
        Format,
        Io,
        Unsupported,
        Gpu,
        NotAvailable,
        Panic,
        Internal,
        Cancelled,
    ]
    .into_iter()
    .find(|s| *s as u32 == v)
}

/// The library version as a static NUL-terminated string, e.g. "0.1.0". It equals the
/// `PLX_VERSION_STRING` macro of the header the host was compiled with when both match.
#[no_mangle]
pub extern "C" fn plx_version() -> *const c_char {
    concat!(env!("CARGO_PKG_VERSION"), "\0").as_ptr().cast()
}

/// Copies the message of the last failed call on `handle` (a `plx_context*` or `plx_scene*`) into
/// `buf`, like `snprintf`: at most `len - 1` bytes and a terminating NUL. With `handle` NULL, the
/// message of the last failed call that had no usable handle (e.g. `plx_context_new`).
///
/// `*needed` (if `needed` is not NULL) receives the full length including the NUL, so a caller can
/// retry with a larger buffer. `buf` may be NULL when `len` is 0. The message is "" when no call
/// has failed. Thread-safe.
///
/// Returns `PLX_STATUS_NULL_ARGUMENT` when `buf` is NULL with `len > 0`,
/// `PLX_STATUS_INVALID_ARGUMENT` when `handle` is not a live Parallax handle.
///
/// # Safety
/// `handle` is NULL or a live handle; `buf` points to `len` writable bytes.
#[no_mangle]
pub unsafe extern "C" fn plx_last_error_message(
    handle: *const c_void,
    buf: *mut c_char,
    len: usize,
    needed: *mut usize,
) -> Status {
    guard(&GLOBAL_ERROR, || {
        if buf.is_null() && len > 0 {
            return Err(null_argument("buf"));
        }
        let slot = error_slot_of(handle as *const HandleHeader)?;
        copy_c_string(&slot.get(), buf, len, needed);
        Ok(())
    })
}

/// `snprintf`-like copy of `text` into `buf` (truncated, NUL-terminated when `len > 0`), writing
/// the full size including the NUL to `*needed` when `needed` is not NULL.
///
/// # Safety
/// `buf` points to `len` writable bytes; `needed` is NULL or writable.
pub(crate) unsafe fn copy_c_string(text: &str, buf: *mut c_char, len: usize, needed: *mut usize) {
    let bytes = text.as_bytes();
    if !needed.is_null() {
        *needed = bytes.len() + 1;
    }
    if len > 0 {
        let n = bytes.len().min(len - 1);
        std::ptr::copy_nonoverlapping(bytes.as_ptr(), buf.cast::<u8>(), n);
        *buf.add(n) = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::ffi::CStr;

    #[test]
    fn every_status_has_its_own_string() {
        let mut seen = std::collections::HashSet::new();
        for v in 0..=12u32 {
            let s = unsafe { CStr::from_ptr(plx_status_str(v)) }
                .to_str()
                .unwrap();
            assert!(seen.insert(s), "{s} repeated");
            assert_eq!(s, status_from_u32(v).unwrap().description());
        }
        let unknown = unsafe { CStr::from_ptr(plx_status_str(999)) };
        assert_eq!(unknown.to_str().unwrap(), "unknown status");
    }

    #[test]
    fn version_matches_cargo() {
        let v = unsafe { CStr::from_ptr(plx_version()) };
        assert_eq!(v.to_str().unwrap(), env!("CARGO_PKG_VERSION"));
    }
}
