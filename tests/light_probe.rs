//! `reference::radiance_probe` against the scene description: a probe below the ceiling light of
//! `room` sees the light's emitted radiance in its direction, and only finite, non-negative
//! radiance anywhere.

use glam::{Mat4, Vec3};
use parallax::light::prefilter::sample_cube;
use parallax::reference::{self, RenderOptions, SampleBudget};

#[test]
fn probe_sees_the_ceiling_light_at_its_radiance() {
    let scene = reference::builtin("room").unwrap();
    let options = RenderOptions {
        width: Some(64),
        height: Some(48),
        samples: SampleBudget::PerPixel(4),
        ..Default::default()
    };
    // The rig's frame comes from a tiny render (its truth carries camera_to_world and the lights
    // in the camera frame).
    let images = reference::render(
        &scene,
        &RenderOptions {
            samples: SampleBudget::PerPixel(1),
            ..options
        },
    )
    .unwrap();
    let to_camera = Mat4::from_cols_array(&images.camera_to_world).inverse();
    let point = to_camera.transform_point3(Vec3::new(0.0, 0.8, -1.6));
    let probe = reference::radiance_probe(&scene, &options, point.to_array(), 16).unwrap();
    assert!(probe
        .texels
        .iter()
        .flatten()
        .all(|v| v.is_finite() && *v >= 0.0));
    let light = Vec3::from(images.lights[0].position.unwrap());
    let seen = sample_cube(&probe, (light - point).normalize());
    let radiance = images.lights[0].radiance.unwrap();
    for k in 0..3 {
        assert!(
            (seen[k] - radiance[k]).abs() < 0.02 * radiance[k],
            "{seen:?} vs {radiance:?}"
        );
    }
    // Straight down is the (dimly lit) table, far darker than the light.
    let down = sample_cube(&probe, to_camera.transform_vector3(-Vec3::Y).normalize());
    assert!(down[0] < 0.2 * radiance[0]);
    assert!(reference::radiance_probe(&scene, &options, [f32::NAN, 0.0, 0.0], 16).is_err());
}

/// The photo re-projected to the insertion point 2 cm above `room`'s table (exact depth) sees
/// below it what the path-traced probe sees there: the lit table top, not the floor the camera
/// sees in front of the table, which the table hides from the point.
#[test]
fn photo_environment_sees_the_table_below_the_point_as_the_probe_does() {
    let scene = reference::builtin("room").unwrap();
    let options = RenderOptions {
        width: Some(96),
        height: Some(72),
        samples: SampleBudget::PerPixel(8),
        ..Default::default()
    };
    let images = reference::render(&scene, &options).unwrap();
    let c = &images.calibration;
    let camera = parallax::camera::Camera::new(
        c.focal_px as f32,
        c.focal_px as f32,
        c.cx as f32,
        c.cy as f32,
        96,
        72,
    )
    .unwrap();
    let to_camera = Mat4::from_cols_array(&images.camera_to_world).inverse();
    let point = to_camera.transform_point3(Vec3::new(0.0, 0.77, -1.6));
    let up = to_camera.transform_vector3(Vec3::Y).normalize();
    let photo = images.left.map(|c| c.map(|v| v.clamp(0.0, 1.0)));
    let env = parallax::light::Environment::from_photo_with_up(
        &photo,
        Some(&images.depth),
        &camera,
        point,
        up,
        &[],
        &Default::default(),
    )
    .unwrap();
    let probe = reference::radiance_probe(
        &scene,
        &RenderOptions {
            samples: SampleBudget::PerPixel(16),
            ..options
        },
        point.to_array(),
        8,
    )
    .unwrap();
    let luminance = parallax::light::luminance;
    let n = probe.size as usize;
    let (mut truth, mut ours, mut count) = (0.0f32, 0.0f32, 0usize);
    for (idx, t) in probe.texels.iter().enumerate() {
        let (f, j, i) = (idx / (n * n), (idx / n) % n, idx % n);
        let d = parallax::light::cube_direction(
            f,
            (i as f32 + 0.5) / n as f32,
            (j as f32 + 0.5) / n as f32,
        );
        if d.dot(up) < -0.7 {
            truth += luminance(*t);
            ours += luminance(sample_cube(&env.cube.levels[0], d));
            count += 1;
        }
    }
    assert!(count > 10);
    let ratio = ours / truth;
    assert!((0.75..1.33).contains(&ratio), "ours {ours} truth {truth}");
}
