//! The panic boundary and error reporting shared by every exported function.

use std::panic::{catch_unwind, AssertUnwindSafe};

use super::handle::ErrorSlot;
use crate::error::{Error, Status};

/// Why an exported call failed: a status and its message.
pub(crate) struct CallError {
    pub status: Status,
    pub message: String,
}

impl From<Error> for CallError {
    fn from(e: Error) -> Self {
        CallError {
            status: e.status(),
            message: e.to_string(),
        }
    }
}

/// `NULL_ARGUMENT` naming the parameter.
pub(crate) fn null_argument(name: &str) -> CallError {
    CallError {
        status: Status::NullArgument,
        message: format!("argument `{name}` is NULL"),
    }
}

/// The `N` floats at `p`, or `None` for NULL: the setters whose NULL means "back to the
/// estimate" (SH9, insertion point, up).
///
/// # Safety
/// `p` is NULL or points to `N` readable floats (any alignment).
pub(crate) unsafe fn optional_floats<const N: usize>(p: *const f32) -> Option<[f32; N]> {
    (!p.is_null()).then(|| std::ptr::read_unaligned(p.cast::<[f32; N]>()))
}

/// `INVALID_ARGUMENT` with a message.
pub(crate) fn invalid(message: impl Into<String>) -> CallError {
    CallError {
        status: Status::InvalidArgument,
        message: message.into(),
    }
}

/// Runs `body`, turning its error or panic into a status and recording the message in `slot`
/// (the handle's, or the process-wide one for calls without a usable handle).
pub(crate) fn guard(slot: &ErrorSlot, body: impl FnOnce() -> Result<(), CallError>) -> Status {
    match catch_unwind(AssertUnwindSafe(body)) {
        Ok(Ok(())) => Status::Ok,
        Ok(Err(e)) => {
            super::log::log(
                super::log::plx_log_level::Error,
                &format!("{:?}: {}", e.status, e.message),
            );
            slot.set(e.message);
            e.status
        }
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic payload".into());
            let message = format!("internal panic: {what}");
            super::log::log(super::log::plx_log_level::Error, &message);
            slot.set(message);
            Status::Panic
        }
    }
}
