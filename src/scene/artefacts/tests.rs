use std::sync::Arc;

use crate::scene::test_support::shifted_pair;
use glam::{Mat4, Vec2, Vec3};

use super::box_glb;
use crate::camera::Camera;
use crate::context::{Context, ContextOptions};
use crate::error::Error;
use crate::image::Raster;
use crate::scene::Scene;
use crate::stereo::StereoOptions;
use crate::trace::StageStatus;

fn scene() -> Scene {
    Scene::new(Arc::new(Context::new(ContextOptions::default()).unwrap()))
}

fn status(scene: &Scene, name: &str) -> StageStatus {
    scene
        .last_trace()
        .stage(name)
        .unwrap_or_else(|| panic!("no stage {name} in {:?}", scene.last_trace().stages()))
        .status
}

fn write(dir: &std::path::Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

#[test]
fn a_file_added_twice_is_loaded_once_and_shared() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(
        dir.path(),
        "box.glb",
        &box_glb([0.0, 0.5, 0.0], [0.5, 0.5, 0.25], [1.0, 0.0, 0.0, 1.0]),
    );
    let mut s = scene();
    let a = s.add_artefact_path(&path, Mat4::IDENTITY).unwrap();
    assert_eq!(status(&s, "artefact.load"), StageStatus::Computed);
    let b = s
        .add_artefact_path(&path, Mat4::from_translation(Vec3::new(2.0, 0.0, -3.0)))
        .unwrap();
    assert_eq!(status(&s, "artefact.load"), StageStatus::Reused);
    let (ia, ib) = (s.artefacts().get(a).unwrap(), s.artefacts().get(b).unwrap());
    assert!(Arc::ptr_eq(&ia.artefact, &ib.artefact));
    assert_eq!(ia.artefact.triangle_count(), 12);

    // Bounds straight from the box's construction: centre (0, 0.5, 0), half (0.5, 0.5, 0.25).
    let bounds = s.artefact_bounds(b).unwrap();
    assert_eq!(bounds.local.min, Vec3::new(-0.5, 0.0, -0.25));
    assert_eq!(bounds.local.max, Vec3::new(0.5, 1.0, 0.25));
    assert_eq!(bounds.world.min, Vec3::new(1.5, 0.0, -3.25));
    assert_eq!(bounds.world.max, Vec3::new(2.5, 1.0, -2.75));

    // A changed file is read again.
    write(
        dir.path(),
        "box.glb",
        &box_glb([0.0; 3], [2.0, 2.0, 2.0], [0.0, 1.0, 0.0, 1.0]),
    );
    let c = s.add_artefact_path(&path, Mat4::IDENTITY).unwrap();
    assert_eq!(status(&s, "artefact.load"), StageStatus::Computed);
    assert_eq!(s.artefact_bounds(c).unwrap().local.max, Vec3::splat(2.0));
    assert_eq!(s.artefacts().len(), 3);
}

#[test]
fn edits_change_the_artefact_version_and_unknown_ids_fail_by_name() {
    let mut s = scene();
    let bytes = box_glb([0.0; 3], [0.1; 3], [0.5; 4]);
    let v0 = s.artefacts_version();
    let id = s.add_artefact_bytes(&bytes, Mat4::IDENTITY).unwrap();
    let v1 = s.artefacts_version();
    assert!(v1 > v0);
    s.set_artefact_visible(id, false).unwrap();
    s.set_artefact_shadows(id, false, true).unwrap();
    let i = s.artefacts().get(id).unwrap();
    assert!(!i.visible && !i.casts_shadow && i.receives_shadow);
    assert!(s.artefacts_version() > v1);

    let mut bad = Mat4::IDENTITY;
    bad.w_axis.y = f32::INFINITY;
    let v2 = s.artefacts_version();
    assert!(matches!(
        s.set_artefact_transform(id, bad),
        Err(Error::InvalidArgument(_))
    ));
    assert!(s.add_artefact_bytes(&bytes, bad).is_err());
    assert_eq!(s.artefacts_version(), v2, "a failed call changes nothing");
    assert_eq!(s.artefacts().len(), 1);

    s.remove_artefact(id).unwrap();
    for e in [
        s.remove_artefact(id).unwrap_err(),
        s.set_artefact_visible(id, true).unwrap_err(),
        s.artefact_bounds(id).unwrap_err(),
        s.place_artefact(id, Vec2::new(1.0, 1.0), 0.2, 0.0)
            .unwrap_err(),
    ] {
        assert!(matches!(e, Error::InvalidArgument(_)));
        assert!(e.to_string().contains(&format!("id {}", id.0)), "{e}");
    }
    // Broken bytes: the loader's error, nothing added.
    let e = s
        .add_artefact_bytes(&bytes[..bytes.len() / 2], Mat4::IDENTITY)
        .unwrap_err();
    assert!(matches!(e, Error::Format(_)), "{e}");
    assert!(s.artefacts().is_empty());
    let e = s
        .add_artefact_path("/nonexistent/parallax/box.glb", Mat4::IDENTITY)
        .unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e}");
}

#[test]
fn moving_an_artefact_does_not_invalidate_reconstruction() {
    let mut s = scene();
    let (l, r) = shifted_pair(64, 32, 4);
    s.set_stereo_pair(&l.view(), &r.view()).unwrap();
    s.set_stereo_options(StereoOptions {
        max_disparity: 8,
        ..Scene::default_stereo_options()
    })
    .unwrap();
    let id = s
        .add_artefact_bytes(&box_glb([0.0; 3], [0.1; 3], [1.0; 4]), Mat4::IDENTITY)
        .unwrap();
    let first = s.depth().unwrap();
    assert_eq!(status(&s, "stereo"), StageStatus::Computed);
    s.set_artefact_transform(id, Mat4::from_translation(Vec3::new(0.0, 0.0, -2.0)))
        .unwrap();
    s.set_artefact_visible(id, false).unwrap();
    let second = s.depth().unwrap();
    assert_eq!(status(&s, "stereo"), StageStatus::Reused);
    assert_eq!(status(&s, "depth"), StageStatus::Reused);
    assert!(Arc::ptr_eq(&first, &second));
    s.remove_artefact(id).unwrap();
    s.depth().unwrap();
    assert_eq!(status(&s, "stereo"), StageStatus::Reused);
}

#[test]
fn a_placed_artefact_stands_on_the_floor_at_its_real_size() {
    // A floor 1 m below the camera and a wall 6 m ahead, exact depth per pixel.
    const W: u32 = 80;
    const H: u32 = 60;
    const F: f32 = 70.0;
    let depth = Raster::from_fn(W as usize, H as usize, |_, y| {
        let dy = -((y as f32 + 0.5) - H as f32 / 2.0) / F;
        let floor = if dy < 0.0 { -1.0 / dy } else { f32::INFINITY };
        floor.min(6.0)
    });
    let mut s = scene();
    s.set_depth(depth, None, Some(Camera::from_focal(F, W, H).unwrap()))
        .unwrap();
    // A box 0.4 × 0.2 × 0.1 m whose own origin is far from its base: placement must use its bounds.
    let id = s
        .add_artefact_bytes(
            &box_glb([3.0, 5.0, -7.0], [0.2, 0.1, 0.05], [1.0; 4]),
            Mat4::IDENTITY,
        )
        .unwrap();
    let placement = s
        .place_artefact(id, Vec2::new(40.5, 50.5), 0.8, 0.0)
        .unwrap();
    assert!((placement.base.y + 1.0).abs() < 0.01, "{}", placement.base);
    let world = s.artefact_bounds(id).unwrap().world;
    // Bottom on the floor, centred on the base point, largest side 0.8 m (scale 2).
    assert!((world.min.y - placement.base.y).abs() < 1e-4, "{world:?}");
    let size = world.size();
    assert!((size.max_element() - 0.8).abs() < 2e-3, "{size}");
    assert!((size.y - 0.4).abs() < 2e-3, "{size}");
    let centre = world.center();
    assert!((centre.x - placement.base.x).abs() < 2e-3);
    assert!((centre.z - placement.base.z).abs() < 2e-3);
    // A pixel without a surface: an error, the transform is kept.
    let before = s.artefacts().get(id).unwrap().transform;
    assert!(s
        .place_artefact(id, Vec2::new(-500.0, 10.0), 0.8, 0.0)
        .is_err());
    assert_eq!(s.artefacts().get(id).unwrap().transform, before);
    assert!(s
        .place_artefact(id, Vec2::new(40.5, 50.5), -1.0, 0.0)
        .is_err());
}
