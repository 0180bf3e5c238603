//! The host's log: one process-wide callback that receives every failed call's message, the
//! warnings of every scene call, and (at finer levels) each product computed, reused or skipped.

use std::ffi::{c_char, c_void, CString};
use std::sync::RwLock;

use super::boundary::{guard, invalid};
use super::handle::GLOBAL_ERROR;
use crate::error::Status;
use crate::trace::{StageRecord, StageStatus};

/// Levels of `plx_log_fn`, most severe first.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum plx_log_level {
    /// A call failed; the message is what `plx_last_error_message` returns for it.
    Error = 0,
    /// A call succeeded but repaired or assumed something (the report's warnings).
    Warn = 1,
    /// A product was computed, with its time.
    Info = 2,
    /// A product was reused or skipped, and why.
    Debug = 3,
}

/// Receives one log line: `level` is a `plx_log_level` value, `message` a NUL-terminated UTF-8
/// string valid only during the call. Called on the thread that made the Parallax call, possibly
/// several threads at once: it must be thread-safe, must not unwind (no C++ exception, no
/// longjmp) and must not call functions on the scene being logged.
pub type plx_log_fn =
    Option<unsafe extern "C" fn(user_data: *mut c_void, level: u32, message: *const c_char)>;

#[derive(Clone, Copy)]
struct Sink {
    callback: unsafe extern "C" fn(*mut c_void, u32, *const c_char),
    user_data: *mut c_void,
    max_level: u32,
}

// The host promises (header) that its callback and user data may be used from any thread.
unsafe impl Send for Sink {}
unsafe impl Sync for Sink {}

static SINK: RwLock<Option<Sink>> = RwLock::new(None);

thread_local! {
    static IN_CALLBACK: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Sets the process-wide log callback (`NULL` = no logging, the default), its `user_data` (passed
/// back unchanged as the first argument) and the most detailed level it wants (`max_level`, a
/// `plx_log_level`: e.g. `PLX_LOG_LEVEL_WARN` gives errors and warnings). Replaces the previous
/// callback; once this returns the previous one is no longer called. Thread-safe. Errors:
/// `INVALID_ARGUMENT` for an unknown level (the callback is then unchanged).
///
/// # Safety
/// `callback` is NULL or a function as described at `plx_log_fn`, valid with `user_data` until it
/// is replaced.
#[no_mangle]
pub unsafe extern "C" fn plx_set_log_callback(
    callback: plx_log_fn,
    user_data: *mut c_void,
    max_level: u32,
) -> Status {
    guard(&GLOBAL_ERROR, || {
        if max_level > plx_log_level::Debug as u32 {
            return Err(invalid(format!(
                "max_level {max_level} is not a plx_log_level (0 error … 3 debug)"
            )));
        }
        let sink = callback.map(|callback| Sink {
            callback,
            user_data,
            max_level,
        });
        *SINK.write().unwrap_or_else(|p| p.into_inner()) = sink;
        Ok(())
    })
}

/// Whether a line of `level` would reach a callback (cheap; lets callers skip formatting).
pub(crate) fn enabled(level: plx_log_level) -> bool {
    SINK.read()
        .map(|s| s.is_some_and(|s| level as u32 <= s.max_level))
        .unwrap_or(false)
}

/// Sends one line to the host's callback, if it wants this level.
pub(crate) fn log(level: plx_log_level, message: &str) {
    // Copied out so that the lock is not held while the host runs (it may set a new callback).
    let sink = match SINK.read() {
        Ok(s) => *s,
        Err(p) => *p.into_inner(),
    };
    let Some(sink) = sink.filter(|s| level as u32 <= s.max_level) else {
        return;
    };
    // A callback that calls Parallax (against the header's advice) and fails would log again:
    // lines raised inside the callback on this thread are dropped instead of recursing.
    if IN_CALLBACK.with(|c| c.replace(true)) {
        return;
    }
    // An interior NUL cannot come from our messages' formatting, but a path could carry one.
    let text = CString::new(message.replace('\0', "\\0")).unwrap_or_default();
    unsafe { (sink.callback)(sink.user_data, level as u32, text.as_ptr()) };
    IN_CALLBACK.with(|c| c.set(false));
}

/// The log line of a trace record: info for computed products, debug for the rest.
pub(crate) fn log_record(scene_tag: usize, record: &StageRecord) {
    let level = match record.status {
        StageStatus::Computed => plx_log_level::Info,
        StageStatus::Reused | StageStatus::Skipped => plx_log_level::Debug,
    };
    if !enabled(level) {
        return;
    }
    let status = match record.status {
        StageStatus::Computed => format!("computed in {:.1} ms", record.ms),
        StageStatus::Reused => "reused".to_string(),
        StageStatus::Skipped => "skipped".to_string(),
    };
    let why = if record.why.is_empty() {
        String::new()
    } else {
        format!(" ({})", record.why)
    };
    log(
        level,
        &format!("scene {scene_tag:#x}: {} {status}{why}", record.name),
    );
}
