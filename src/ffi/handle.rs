//! Handles: a heap box with a type tag and an error slot in front of the Rust value.
//!
//! The C side sees opaque pointers (`plx_context*`, `plx_scene*`). Each points to a
//! `Handle<T>`, whose `#[repr(C)]` layout puts the [`HandleHeader`] first so that
//! `plx_last_error_message(const void*)` can read the error of any handle kind.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

use super::boundary::{invalid, null_argument, CallError};

/// The message of the last failed call on one handle.
#[derive(Debug, Default)]
pub(crate) struct ErrorSlot(Mutex<String>);

impl ErrorSlot {
    pub(crate) const fn new() -> Self {
        ErrorSlot(Mutex::new(String::new()))
    }

    pub(crate) fn set(&self, message: String) {
        // A poisoned lock only means an earlier panic while holding it; the String is still valid.
        let mut m = self.0.lock().unwrap_or_else(|p| p.into_inner());
        *m = message;
    }

    pub(crate) fn get(&self) -> String {
        self.0.lock().unwrap_or_else(|p| p.into_inner()).clone()
    }
}

/// Errors of calls that had no usable handle to attach them to (a failed `plx_context_new`,
/// a NULL handle). `plx_last_error_message(NULL, …)` reads it.
pub(crate) static GLOBAL_ERROR: ErrorSlot = ErrorSlot::new();

/// Type tags, so that passing a context where a scene is expected is an error, not memory
/// corruption. (A freed handle's tag is overwritten before its memory is released, which helps
/// debugging tools; using a freed handle remains undefined behaviour, as in any C API.)
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u64)]
pub(crate) enum Kind {
    Context = 0x706c_7843_7478_0001,
    Scene = 0x706c_7853_636e_0002,
    Freed = 0x706c_7846_7265_0000,
}

#[repr(C)]
pub(crate) struct HandleHeader {
    kind: u64,
    pub error: ErrorSlot,
    /// Set while a call uses the handle's value ([`Handle::enter`]), so that a call from a
    /// callback of that same call, or from a second thread at the same time, fails cleanly
    /// instead of aliasing the value.
    busy: AtomicBool,
}

#[repr(C)]
pub(crate) struct Handle<T> {
    pub header: HandleHeader,
    pub value: T,
}

impl<T> Handle<T> {
    /// Boxes `value` and returns the raw pointer given to C.
    pub(crate) fn into_raw(kind: Kind, value: T) -> *mut Handle<T> {
        Box::into_raw(Box::new(Handle {
            header: HandleHeader {
                kind: kind as u64,
                error: ErrorSlot::new(),
                busy: AtomicBool::new(false),
            },
            value,
        }))
    }

    /// Frees a handle made by `into_raw` (NULL is allowed).
    ///
    /// # Safety
    /// `ptr` is NULL or came from `into_raw` with this `kind` and was not freed.
    pub(crate) unsafe fn free(ptr: *mut Handle<T>, kind: Kind) {
        if ptr.is_null() || (*ptr).header.kind != kind as u64 {
            return;
        }
        // Freed from inside one of its own calls (a callback): freeing now would pull the value
        // from under that call, so the handle is left alone.
        if (*ptr).header.busy.load(Ordering::Acquire) {
            return;
        }
        (*ptr).header.kind = Kind::Freed as u64;
        drop(Box::from_raw(ptr));
    }

    /// Borrows the handle behind `ptr`, checking NULL and the type tag.
    ///
    /// # Safety
    /// `ptr` is NULL or points to a live handle (of any kind).
    pub(crate) unsafe fn from_ptr<'a>(
        ptr: *const Handle<T>,
        kind: Kind,
        name: &str,
    ) -> Result<&'a Handle<T>, CallError> {
        if ptr.is_null() {
            return Err(null_argument(name));
        }
        check_kind(ptr as *const HandleHeader, kind, name)?;
        Ok(&*ptr)
    }

    /// Exclusive use of the value behind `ptr` for one call: its header (for the error slot) and
    /// its value as separate borrows. Fails with the header when another call is using the
    /// value (re-entered from a callback, or a second thread), `Err((None, …))` for NULL or a
    /// foreign pointer. The value is released when the returned [`Entered`] drops.
    ///
    /// # Safety
    /// `ptr` is NULL or points to a live handle (of any kind).
    pub(crate) unsafe fn enter<'a>(
        ptr: *mut Handle<T>,
        kind: Kind,
        name: &str,
    ) -> Result<Entered<'a, T>, (Option<&'a HandleHeader>, CallError)> {
        if ptr.is_null() {
            return Err((None, null_argument(name)));
        }
        check_kind(ptr as *const HandleHeader, kind, name).map_err(|e| (None, e))?;
        // Field projections through the raw pointer: the header may be shared with a concurrent
        // call, the value is borrowed mutably only after winning the busy flag.
        let header = &*std::ptr::addr_of!((*ptr).header);
        if header.busy.swap(true, Ordering::Acquire) {
            return Err((
                Some(header),
                invalid(format!(
                    "`{name}` is busy with another call: a callback called back into it, or two \
                     threads used it at once"
                )),
            ));
        }
        Ok(Entered {
            header,
            value: &mut *std::ptr::addr_of_mut!((*ptr).value),
        })
    }
}

/// A handle in use by one call (see [`Handle::enter`]).
pub(crate) struct Entered<'a, T> {
    pub header: &'a HandleHeader,
    pub value: &'a mut T,
}

impl<T> Drop for Entered<'_, T> {
    fn drop(&mut self) {
        self.header.busy.store(false, Ordering::Release);
    }
}

unsafe fn check_kind(header: *const HandleHeader, kind: Kind, name: &str) -> Result<(), CallError> {
    let found = (*header).kind;
    if found == kind as u64 {
        Ok(())
    } else {
        Err(invalid(format!("`{name}` is not a live {kind:?} handle")))
    }
}

/// The error slot of any handle, or the global one for NULL.
///
/// # Safety
/// `ptr` is NULL or points to a live handle of any kind.
pub(crate) unsafe fn error_slot_of<'a>(
    ptr: *const HandleHeader,
) -> Result<&'a ErrorSlot, CallError> {
    if ptr.is_null() {
        return Ok(&GLOBAL_ERROR);
    }
    let kind = (*ptr).kind;
    if kind == Kind::Context as u64 || kind == Kind::Scene as u64 {
        Ok(&(*ptr).error)
    } else {
        Err(invalid("`handle` is not a live Parallax handle"))
    }
}
