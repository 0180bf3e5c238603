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
