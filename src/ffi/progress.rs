//! Per-scene progress with cancellation, and the bridge from a scene's trace to the host's log.

use std::ffi::{c_char, c_void, CString};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

use super::log::{log, log_record, plx_log_level};
use super::scene::{plx_scene, with_scene_state};
use crate::error::Status;
use crate::trace::{Observer, StageRecord, TraceObserver};

/// Receives a scene's progress: `stage` is the product's name (NUL-terminated, valid only during
/// the call; e.g. "stereo", "depth", "mesh.grid", "surfaces"), `fraction` 0 when it starts and 1
/// when it is done. Return 0 to go on, nonzero to cancel: the call then returns
/// `PLX_STATUS_CANCELLED`, before that product (at 0) or right after it (at 1; the product is
/// kept, so asking again resumes from there). The scene is unchanged otherwise. Called on the
/// thread that made the call; it must not unwind (no C++ exception, no longjmp) and must not call
/// functions on that scene (they fail as busy).
pub type plx_progress_fn = Option<
    unsafe extern "C" fn(user_data: *mut c_void, stage: *const c_char, fraction: f32) -> i32,
>;

#[derive(Clone, Copy)]
struct ProgressSink {
    callback: unsafe extern "C" fn(*mut c_void, *const c_char, f32) -> i32,
    user_data: *mut c_void,
}

// The callback runs only on the thread making a call on the scene (the host's promise for a
// scene, which is used by one thread at a time).
unsafe impl Send for ProgressSink {}

/// What a C scene hands its trace: the host's progress callback and the log bridge.
#[derive(Default)]
pub(crate) struct SceneHooks {
    progress: Mutex<Option<ProgressSink>>,
    /// The handle's address, naming the scene in log lines (0 until the handle exists).
    tag: AtomicUsize,
}

impl SceneHooks {
    /// New hooks for the scene handle at `tag`, with the progress callback of `from` (a clone).
    pub(crate) fn new_observer(from: Option<&SceneHooks>) -> Arc<SceneHooks> {
        let progress = from.and_then(|h| *h.progress.lock().unwrap_or_else(|p| p.into_inner()));
        Arc::new(SceneHooks {
            progress: Mutex::new(progress),
            tag: AtomicUsize::new(0),
        })
    }

    pub(crate) fn set_tag(&self, tag: usize) {
        self.tag.store(tag, Ordering::Relaxed);
    }

    pub(crate) fn observer(self: &Arc<Self>) -> Observer {
        Observer(Arc::clone(self) as Arc<dyn TraceObserver>)
    }
}

impl TraceObserver for SceneHooks {
    fn progress(&self, stage: &str, fraction: f32) -> bool {
        let sink = *self.progress.lock().unwrap_or_else(|p| p.into_inner());
        let Some(sink) = sink else {
            return true;
        };
        let name = CString::new(stage).unwrap_or_default();
        unsafe { (sink.callback)(sink.user_data, name.as_ptr(), fraction) == 0 }
    }

    fn record(&self, record: &StageRecord) {
        log_record(self.tag.load(Ordering::Relaxed), record);
    }

    fn warning(&self, message: &str) {
        let tag = self.tag.load(Ordering::Relaxed);
        log(plx_log_level::Warn, &format!("scene {tag:#x}: {message}"));
    }
}

/// Sets the scene's progress callback (`NULL` = none, the default) and its `user_data` (passed
/// back unchanged as the first argument). Every later call that computes products reports each
/// one as it starts and finishes; see `plx_progress_fn` for cancelling. Progress is reported
/// between products: one long product (stereo matching of a large pair) is not interrupted
/// inside. `plx_scene_clone` copies the callback.
///
/// # Safety
/// `scene` is a live scene; `callback` is NULL or a function as described at `plx_progress_fn`,
/// valid with `user_data` until it is replaced or the scene is freed.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_set_progress_callback(
    scene: *mut plx_scene,
    callback: plx_progress_fn,
    user_data: *mut c_void,
) -> Status {
    with_scene_state(scene, |state| {
        *state
            .hooks
            .progress
            .lock()
            .unwrap_or_else(|p| p.into_inner()) = callback.map(|callback| ProgressSink {
            callback,
            user_data,
        });
        Ok(())
    })
}
