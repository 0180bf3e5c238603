use std::sync::Arc;

use crate::scene::test_support::shifted_pair;
use glam::{Vec2, Vec3};

use crate::camera::{Camera, DepthEncoding};
use crate::context::{Context, ContextOptions};
use crate::error::Error;
use crate::image::{Image, PixelFormat, Raster};
use crate::mesh::{MeshOptions, PlaceOptions, SurfaceKind, UpSource};
use crate::scene::Scene;
use crate::stereo::StereoOptions;
use crate::trace::StageStatus;

const W: u32 = 80;
const H: u32 = 60;
const F: f32 = 70.0;
const FLOOR_Y: f32 = -1.0;
const WALL_Z: f32 = -6.0;

fn scene() -> Scene {
    Scene::new(Arc::new(Context::new(ContextOptions::default()).unwrap()))
}

fn camera() -> Camera {
    Camera::from_focal(F, W, H).unwrap()
}

/// Exact depth of a floor at y = −1 m below the camera and a wall 6 m ahead, at the centre of
/// pixel (x, y): the ray through it is `(dx, dy, −1)·Z`, so depth along the axis of both (a
/// horizontal floor and a fronto-parallel wall) depends on the row only.
fn room_depth(_x: usize, y: usize) -> f32 {
    let dy = -((y as f32 + 0.5) - H as f32 / 2.0) / F;
    let floor = if dy < 0.0 {
        FLOOR_Y / dy
    } else {
        f32::INFINITY
    };
    floor.min(-WALL_Z)
}

fn room() -> Raster<f32> {
    Raster::from_fn(W as usize, H as usize, room_depth)
}

fn status(scene: &Scene, name: &str) -> StageStatus {
    scene
        .last_trace()
        .stage(name)
        .unwrap_or_else(|| panic!("no stage {name} in {:?}", scene.last_trace().stages()))
        .status
}

#[test]
fn host_depth_skips_stereo_and_feeds_the_mesh() {
    let mut s = scene();
    let mut depth = room();
    *depth.get_mut(3, 50) = -2.0;
    *depth.get_mut(4, 50) = f32::INFINITY;
    s.set_depth(depth, None, Some(camera())).unwrap();
    let mesh = s.mesh().unwrap();
    assert_eq!(status(&s, "stereo"), StageStatus::Skipped);
    assert_eq!(
        s.last_trace().stage("stereo").unwrap().why,
        "host depth given"
    );
    assert_eq!(status(&s, "mesh.grid"), StageStatus::Computed);
    assert!(mesh.triangle_count() > 0);
    // Negative and infinite host depth became holes.
    let d = s.depth().unwrap();
    assert!(d.get(3, 50).is_nan() && d.get(4, 50).is_nan());
    assert_eq!(*d.get(40, 50), room_depth(40, 50));
    for p in &mesh.positions {
        assert!(Vec3::from(*p).is_finite());
    }
    assert!(mesh
        .indices
        .iter()
        .all(|&i| (i as usize) < mesh.vertex_count()));
}

#[test]
fn clip_planes_recompute_the_depth_buffer_but_not_the_mesh() {
    let mut s = scene();
    s.set_depth(room(), None, Some(camera())).unwrap();
    let mesh = s.mesh().unwrap();
    let buffer = s.depth_buffer(DepthEncoding::ReversedZ).unwrap();
    let cam = s.camera().unwrap();
    // Auto clip from the depth range: the nearest floor pixel and the wall, with margins.
    let nearest = room_depth(0, H as usize - 1);
    assert!((cam.near - 0.5 * nearest).abs() < 1e-5, "{}", cam.near);
    assert!((cam.far - 2.0 * 6.0).abs() < 1e-4, "{}", cam.far);
    let (near, far) = (cam.near as f64, cam.far as f64);
    let z = room_depth(10, 50) as f64;
    let expect = near * (far - z) / ((far - near) * z);
    assert!((*buffer.get(10, 50) as f64 - expect).abs() < 1e-6);

    s.set_clip(0.1, 100.0).unwrap();
    let buffer = s.depth_buffer(DepthEncoding::OpenGlWindow).unwrap();
    assert_eq!(status(&s, "camera"), StageStatus::Computed);
    assert_eq!(status(&s, "depth_buffer"), StageStatus::Computed);
    let (n, f) = (0.1f64, 100.0f64);
    let expect = (f + n) / (2.0 * (f - n)) - f * n / ((f - n) * z) + 0.5;
    assert!((*buffer.get(10, 50) as f64 - expect).abs() < 1e-6);
    // Linear metres: depth itself, +inf where none.
    let linear = s.depth_buffer(DepthEncoding::LinearMeters).unwrap();
    assert_eq!(*linear.get(10, 50), room_depth(10, 50));

    let again = s.mesh().unwrap();
    assert_eq!(status(&s, "mesh.grid"), StageStatus::Reused);
    assert_eq!(status(&s, "mesh"), StageStatus::Reused);
    assert!(Arc::ptr_eq(&mesh, &again));

    // A per-call clip range is checked like set_clip.
    assert!(s
        .depth_buffer_with_clip(DepthEncoding::WebGpuZeroToOne, Some((5.0, 5.0)))
        .is_err());
    let own = s
        .depth_buffer_with_clip(DepthEncoding::WebGpuZeroToOne, Some((1.0, 10.0)))
        .unwrap();
    let expect = 10.0 * (z - 1.0) / (9.0 * z);
    assert!((*own.get(10, 50) as f64 - expect).abs() < 1e-6);
}

#[test]
fn triangle_budget_resimplifies_without_rebuilding_the_grid_or_surfaces() {
    let mut s = scene();
    s.set_depth(room(), None, Some(camera())).unwrap();
    let full = s.mesh().unwrap();
    assert_eq!(status(&s, "mesh.simplify"), StageStatus::Skipped);
    s.surfaces().unwrap();
    s.set_mesh_options(MeshOptions {
        max_triangles: Some(200),
        ..MeshOptions::default()
    })
    .unwrap();
    let small = s.mesh().unwrap();
    assert_eq!(status(&s, "mesh.grid"), StageStatus::Reused);
    assert_eq!(status(&s, "mesh.simplify"), StageStatus::Computed);
    assert!(small.triangle_count() <= 200 && small.triangle_count() < full.triangle_count());
    s.surfaces().unwrap();
    assert_eq!(status(&s, "surfaces"), StageStatus::Reused);
    s.bvh().unwrap();
    assert_eq!(status(&s, "bvh"), StageStatus::Computed);
    assert!(s
        .set_mesh_options(MeshOptions {
            step: 0,
            ..MeshOptions::default()
        })
        .is_err());
}

#[test]
fn pick_place_and_surfaces_match_the_analytic_room() {
    let mut s = scene();
    s.set_depth(room(), None, Some(camera())).unwrap();
    // Pixel (40, 50) sees the floor.
    let pixel = Vec2::new(40.5, 50.5);
    let hit = s.pick(pixel).unwrap().expect("the floor is there");
    let truth = camera()
        .unproject(pixel.x, pixel.y, room_depth(40, 50))
        .unwrap();
    assert!(
        (hit.point - truth).length() < 1e-3 * truth.length(),
        "{hit:?} vs {truth}"
    );
    assert!(hit.normal.angle_between(Vec3::Y).to_degrees() < 2.0);
    assert!(s.pick(Vec2::new(f32::NAN, 1.0)).is_err());
    assert!(s.pick(Vec2::new(-500.0, 30.0)).unwrap().is_none());

    let surfaces = s.surfaces().unwrap();
    assert_eq!(surfaces.up_source, UpSource::Planes);
    assert!(surfaces.up.angle_between(Vec3::Y).to_degrees() < 3.0);
    assert!(surfaces
        .surfaces
        .iter()
        .any(|p| p.kind == SurfaceKind::Horizontal && (p.offset - FLOOR_Y).abs() < 0.02));

    let placed = s.place(pixel, 0.3, 0.0, &PlaceOptions::default()).unwrap();
    assert!((placed.base.y - FLOOR_Y).abs() < 0.01, "{}", placed.base);
    assert!(placed.up.angle_between(Vec3::Y).to_degrees() < 3.0);
    // The model's base centre (origin) maps to the base point.
    let base = placed.transform.transform_point3(Vec3::ZERO);
    assert!((base - placed.base).length() < 1e-4);
    // Straight down from 1 m above the floor point.
    let ray = crate::mesh::Ray::new(truth + Vec3::Y, Vec3::NEG_Y);
    let on_ray = s
        .place_on_ray(&ray, 0.3, 0.5, &PlaceOptions::default())
        .unwrap();
    assert!((on_ray.base - truth).length() < 0.01);
    assert!(s
        .place(Vec2::new(-500.0, 30.0), 0.3, 0.0, &PlaceOptions::default())
        .is_err());
}

#[test]
fn bad_host_depth_is_rejected_or_reported() {
    let mut s = scene();
    let mut wrong = camera();
    wrong.width = 81;
    assert!(matches!(
        s.set_depth(room(), None, Some(wrong)),
        Err(Error::SizeMismatch(_))
    ));
    let conf = Raster::filled(W as usize, H as usize, 2.0);
    assert!(s.set_depth(room(), Some(conf), None).is_err());
    let conf = Raster::filled(3, 3, 1.0);
    assert!(matches!(
        s.set_depth(room(), Some(conf), None),
        Err(Error::SizeMismatch(_))
    ));
    assert!(s.set_depth(Raster::filled(0, 0, 1.0), None, None).is_err());
    assert!(s.host_depth().is_none());
    assert!(matches!(s.mesh(), Err(Error::NotAvailable(_))));
    assert!(s.set_clip(0.0, 1.0).is_err());
    assert!(s.set_clip(2.0, 2.0).is_err());
    assert!(s.set_clip(1.0, f32::INFINITY).is_err());

    // A stereo pair of another size than the host depth, either way round.
    let img = Image::from_bytes(8, 4, PixelFormat::Gray8, vec![0; 32]).unwrap();
    s.set_depth(room(), None, None).unwrap();
    assert!(matches!(
        s.set_stereo_pair(&img.view(), &img.view()),
        Err(Error::SizeMismatch(_))
    ));
    s.clear_depth();
    s.set_stereo_pair(&img.view(), &img.view()).unwrap();
    assert!(matches!(
        s.set_depth(room(), None, None),
        Err(Error::SizeMismatch(_))
    ));

    // All depth invalid (NaN, or zero confidence): the mesh fails clearly, surfaces are empty.
    let mut s = scene();
    let zero_conf = Raster::filled(W as usize, H as usize, 0.0);
    s.set_depth(room(), Some(zero_conf), None).unwrap();
    let err = s.mesh().unwrap_err();
    assert!(err.to_string().contains("no valid"), "{err}");
    let surfaces = s.surfaces().unwrap();
    assert!(surfaces.surfaces.is_empty());
    assert_eq!(surfaces.up_source, UpSource::CameraFallback);
    assert_eq!(s.last_trace().warnings().len(), 2, "{:?}", s.last_trace());
    assert!(s.camera().is_err());
    // With an explicit clip range the depth buffer exists: all empty.
    let buffer = s
        .depth_buffer_with_clip(DepthEncoding::ReversedZ, Some((0.1, 10.0)))
        .unwrap();
    assert!(buffer.pixels().iter().all(|&v| v == 0.0));

    // One pixel: no triangle possible.
    let mut s = scene();
    s.set_depth(Raster::filled(1, 1, 2.0), None, None).unwrap();
    assert!(s.mesh().is_err());
    assert!(s.surfaces().unwrap().surfaces.is_empty());
    assert!(s.camera().unwrap().near > 0.0);
}

#[test]
fn extreme_fields_of_view_give_finite_meshes() {
    for fov in [1.0, 170.0] {
        let mut s = scene();
        let cam = Camera::from_fov(fov, W, H).unwrap();
        // A fronto-parallel plane 3 m away.
        s.set_depth(Raster::filled(W as usize, H as usize, 3.0), None, Some(cam))
            .unwrap();
        let mesh = s.mesh().unwrap();
        assert!(mesh.triangle_count() > 0, "fov {fov}");
        assert!(mesh
            .positions
            .iter()
            .chain(&mesh.normals)
            .all(|p| Vec3::from(*p).is_finite()));
        let hit = s.pick(Vec2::new(40.0, 30.0)).unwrap().unwrap();
        assert!((hit.point.z + 3.0).abs() < 1e-3, "fov {fov}: {hit:?}");
    }
}

#[test]
fn stereo_feeds_the_mesh_and_mesh_options_do_not_rematch() {
    let mut s = scene();
    let (l, r) = shifted_pair(96, 48, 6);
    s.set_stereo_pair(&l.view(), &r.view()).unwrap();
    s.set_stereo_options(StereoOptions {
        max_disparity: 16,
        ..Scene::default_stereo_options()
    })
    .unwrap();
    s.set_calibration(
        crate::camera::StereoCalibration::from_focal_baseline(600.0, 0.1, 96, 48).unwrap(),
    )
    .unwrap();
    let mesh = s.mesh().unwrap();
    assert_eq!(status(&s, "stereo"), StageStatus::Computed);
    assert_eq!(status(&s, "depth"), StageStatus::Computed);
    // A plane at Z = f·B/d = 10 m: the mesh centre lies there.
    let hit = s.pick(Vec2::new(60.0, 24.0)).unwrap().unwrap();
    assert!((hit.point.z + 10.0).abs() < 0.5, "{hit:?}");
    assert_eq!(status(&s, "stereo"), StageStatus::Reused);
    s.set_mesh_options(MeshOptions {
        step: 2,
        ..MeshOptions::default()
    })
    .unwrap();
    let coarse = s.mesh().unwrap();
    assert_eq!(status(&s, "stereo"), StageStatus::Reused);
    assert_eq!(status(&s, "depth"), StageStatus::Reused);
    assert_eq!(status(&s, "mesh.grid"), StageStatus::Computed);
    assert!(coarse.vertex_count() < mesh.vertex_count());

    // Host depth replaces stereo; clearing it brings stereo back (its cache intact).
    s.set_depth(Raster::filled(96, 48, 4.0), None, None)
        .unwrap();
    let hit = s.pick(Vec2::new(60.0, 24.0)).unwrap().unwrap();
    assert!((hit.point.z + 4.0).abs() < 1e-3);
    assert_eq!(status(&s, "stereo"), StageStatus::Skipped);
    s.clear_depth();
    s.mesh().unwrap();
    assert_eq!(status(&s, "stereo"), StageStatus::Reused);
    assert_eq!(status(&s, "depth"), StageStatus::Computed);
}

#[test]
fn the_hosts_gravity_up_classifies_surfaces_and_stands_objects_along_it() {
    let mut s = scene();
    s.set_depth(room(), None, Some(camera())).unwrap();
    assert_eq!(s.surfaces().unwrap().up_source, UpSource::Planes);
    // An IMU that says the camera is rolled 20°: the floor is no longer horizontal under it.
    let tilted = Vec3::new(20f32.to_radians().sin(), 20f32.to_radians().cos(), 0.0);
    s.set_up((tilted * 3.0).to_array()).unwrap();
    let surfaces = s.surfaces().unwrap();
    assert_eq!(status(&s, "surfaces"), StageStatus::Computed);
    assert_eq!(status(&s, "mesh.grid"), StageStatus::Reused);
    assert_eq!(surfaces.up_source, UpSource::Host);
    assert!(surfaces.up.angle_between(tilted) < 1e-5, "{}", surfaces.up);
    let floor = surfaces
        .surfaces
        .iter()
        .find(|p| (p.offset - FLOOR_Y).abs() < 0.02)
        .expect("the floor is still found");
    assert_eq!(floor.kind, SurfaceKind::Slanted);
    let placed = s
        .place(
            Vec2::new(40.5, 50.5),
            0.3,
            0.0,
            &PlaceOptions {
                orientation: crate::mesh::Orientation::Gravity,
                ..PlaceOptions::default()
            },
        )
        .unwrap();
    assert!(placed.up.angle_between(tilted) < 1e-4, "{}", placed.up);
    // The same up again changes nothing; a zero or NaN up is refused and changes nothing.
    s.set_up((tilted * 3.0).to_array()).unwrap();
    s.surfaces().unwrap();
    assert_eq!(status(&s, "surfaces"), StageStatus::Reused);
    for bad in [[0.0; 3], [f32::NAN, 1.0, 0.0]] {
        let e = s.set_up(bad).unwrap_err();
        assert!(e.to_string().contains("up must be"), "{e}");
    }
    assert_eq!(s.surfaces().unwrap().up_source, UpSource::Host);
    s.clear_up();
    let surfaces = s.surfaces().unwrap();
    assert_eq!(surfaces.up_source, UpSource::Planes);
    assert!(surfaces.up.angle_between(Vec3::Y).to_degrees() < 3.0);
}

#[test]
fn mesh_normals_snap_to_the_surfaces_unless_turned_off() {
    // The analytic room with 0.3 % of deterministic depth ripple: the local fits scatter.
    let rippled = Raster::from_fn(W as usize, H as usize, |x, y| {
        let phase = (x * 7 + y * 13) as f32;
        room_depth(x, y) * (1.0 + 0.003 * phase.sin())
    });
    let mut s = scene();
    s.set_depth(rippled, None, Some(camera())).unwrap();
    let snapped = s.mesh().unwrap();
    assert_eq!(status(&s, "mesh.snap"), StageStatus::Computed);
    let floor = s
        .surfaces()
        .unwrap()
        .surfaces
        .iter()
        .find(|s| s.kind == SurfaceKind::Horizontal)
        .expect("the floor is found")
        .normal;
    // The floor vertices away from the wall have the floor plane's normal, exactly (but for a
    // few at the border of its image polygon).
    let floor_vertices: Vec<usize> = (0..snapped.vertex_count())
        .filter(|&k| snapped.uvs[k][1] * H as f32 > 45.0)
        .collect();
    let on_plane = floor_vertices
        .iter()
        .filter(|&&k| Vec3::from(snapped.normals[k]).angle_between(floor) < 1e-4)
        .count();
    assert!(
        floor_vertices.len() > 500 && on_plane * 10 > floor_vertices.len() * 9,
        "{on_plane} of {}",
        floor_vertices.len()
    );
    s.set_mesh_options(MeshOptions {
        snap_to_surfaces: false,
        ..MeshOptions::default()
    })
    .unwrap();
    let own = s.mesh().unwrap();
    assert_eq!(status(&s, "mesh.snap"), StageStatus::Skipped);
    assert_eq!(status(&s, "mesh.grid"), StageStatus::Reused);
    let differ = floor_vertices
        .iter()
        .filter(|&&k| Vec3::from(own.normals[k]).angle_between(floor).to_degrees() > 0.1)
        .count();
    assert!(differ * 2 > floor_vertices.len(), "{differ} differ");
}

#[test]
fn a_pair_with_nothing_to_match_is_warned_of_and_a_textured_one_is_not() {
    let mut s = scene();
    let flat = Image::from_bytes(W, H, PixelFormat::Gray8, vec![120; (W * H) as usize]).unwrap();
    s.set_stereo_pair(&flat.view(), &flat.view()).unwrap();
    let d = s.disparity().unwrap();
    assert!(d.confidence.pixels().iter().all(|&c| c == 0.0));
    let warned = |s: &Scene| {
        s.last_trace()
            .warnings()
            .iter()
            .any(|w| w.contains("nothing to match"))
    };
    assert!(warned(&s), "{:?}", s.last_trace().warnings());
    let (l, r) = shifted_pair(W, H, 4);
    s.set_stereo_pair(&l.view(), &r.view()).unwrap();
    s.disparity().unwrap();
    assert!(!warned(&s), "{:?}", s.last_trace().warnings());
}
