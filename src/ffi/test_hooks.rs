//! Entry points that exist only to test the C boundary itself (feature `test-hooks`).

use super::scene::plx_scene;
use crate::error::Status;

/// Panics inside the boundary on purpose: must return `PLX_STATUS_PANIC` with a message on the
/// scene, and leave the scene usable.
///
/// # Safety
/// `scene` is a live scene.
#[no_mangle]
pub unsafe extern "C" fn plx_test_panic(scene: *mut plx_scene) -> Status {
    super::scene::with_scene_for_tests(scene, || panic!("plx_test_panic was called"))
}
