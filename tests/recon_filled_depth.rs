//! The `Scene` hands the stereo matcher's confidence on to the mesh's normal snapping and to
//! placement. On a noisy path-traced render of `clutter` most of the depth is filled, and what
//! the Scene gives is what those steps give with the confidence, not without it.

use std::sync::Arc;

use glam::Vec2;
use parallax::context::{Context, ContextOptions};
use parallax::image::{Image, Raster};
use parallax::mesh::{MeshOptions, PlaceOptions, PlacementScene, SceneMesh, SurfaceOptions};
use parallax::reference::{self, RenderOptions, SampleBudget};
use parallax::scene::Scene;

#[test]
fn the_scene_snaps_normals_and_places_with_the_matchers_confidence() {
    // 4 samples per pixel: noisier than the eval's 16, so that much of the floor is filled and
    // its normals agree on no direction.
    let images = reference::render(
        &reference::builtin("clutter").unwrap(),
        &RenderOptions {
            width: Some(240),
            height: Some(180),
            samples: SampleBudget::PerPixel(4),
            ..RenderOptions::default()
        },
    )
    .unwrap();
    let mut scene = Scene::new(Arc::new(Context::new(ContextOptions::default()).unwrap()));
    let (left, right) = (
        Image::from_linear_rgb(&images.left),
        Image::from_linear_rgb(&images.right),
    );
    scene.set_stereo_pair(&left.view(), &right.view()).unwrap();
    scene.set_calibration(images.calibration).unwrap();

    let snapped = scene.mesh().unwrap();
    let bvh = scene.bvh().unwrap();
    let surfaces = scene.surfaces().unwrap();
    let camera = scene.camera().unwrap();
    let confidence = scene.disparity().unwrap().confidence.clone();
    let filled = confidence.pixels().iter().filter(|&&c| c <= 0.0).count();
    assert!(
        filled * 4 > confidence.len(),
        "{filled} of {} pixels filled",
        confidence.len()
    );

    // Placement: wherever the confidence changes where an object goes, the Scene's goes there.
    let trusting = PlacementScene {
        bvh: &bvh,
        camera: &camera,
        surfaces: &surfaces,
        confidence: Some(&confidence),
    };
    let blind = PlacementScene {
        confidence: None,
        ..trusting
    };
    let options = PlaceOptions::default();
    let mut differing = 0;
    for y in (5..180).step_by(10) {
        for x in (5..240).step_by(10) {
            let pixel = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            let (Ok(with), Ok(without)) = (
                trusting.place(pixel, 0.2, 0.0, &options),
                blind.place(pixel, 0.2, 0.0, &options),
            ) else {
                continue;
            };
            if with != without {
                differing += 1;
                assert_eq!(scene.place(pixel, 0.2, 0.0, &options).unwrap(), with);
            }
        }
    }
    assert!(differing > 0, "no placement depends on the confidence");

    // Normals: the Scene's snapped mesh is its grid snapped with the confidence.
    scene
        .set_mesh_options(MeshOptions {
            snap_to_surfaces: false,
            ..MeshOptions::default()
        })
        .unwrap();
    let grid = scene.mesh().unwrap();
    let surface_options = SurfaceOptions::default();
    let snapped_with = |confidence: Option<&Raster<f32>>| {
        let mut mesh = SceneMesh::clone(&grid);
        surfaces.snap_mesh_normals_with_confidence(
            &mut mesh,
            &camera,
            confidence,
            surface_options.membership_tolerance(),
            surface_options.membership_normal_tolerance_deg(),
        );
        mesh.normals
    };
    let differing =
        |a: &[[f32; 3]], b: &[[f32; 3]]| a.iter().zip(b).filter(|(a, b)| a != b).count();
    let with = snapped_with(Some(&confidence));
    let by_confidence = differing(&with, &snapped_with(None));
    assert!(by_confidence > 0, "the confidence changes no normal");
    assert_eq!(snapped.normals.len(), with.len());
    assert_eq!(
        differing(&snapped.normals, &with),
        0,
        "the Scene's normals are not those snapped with the confidence (which changes {by_confidence})"
    );
}
