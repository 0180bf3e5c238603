//! The reference's correctness tests: each compares against an analytic value.

use super::*;
use crate::camera::StereoCalibration;

fn rig(width: u32, height: u32, position: [f32; 3], look_at: [f32; 3]) -> CameraRig {
    CameraRig {
        width,
        height,
        fov_x_deg: Some(50.0),
        focal_px: None,
        baseline_m: 0.058,
        position,
        look_at,
        up: [0.0, 1.0, 0.0],
    }
}

fn spp(n: u32, bounces: u32) -> RenderOptions {
    RenderOptions {
        samples: SampleBudget::PerPixel(n),
        max_bounces: bounces,
        ..RenderOptions::default()
    }
}

fn furnace(shape: Shape, bounces: u32) -> Images {
    let scene = Scene {
        name: "furnace".into(),
        camera: rig(32, 24, [0.0, 0.0, 4.0], [0.0, 0.0, 0.0]),
        objects: vec![Object {
            name: "white".into(),
            shape,
            material: Material::lambert([1.0; 3]),
            transform: Transform::default(),
        }],
        lights: vec![],
        environment: Environment::Constant { radiance: [1.0; 3] },
        portals: Vec::new(),
    };
    render(&scene, &spp(32, bounces)).unwrap()
}

/// A white Lambertian object in a uniform white environment is invisible: every pixel shows the
/// environment's radiance, within the render's own noise estimate.
fn assert_furnace(images: &Images, what: &str) {
    let variance = images.variance.as_ref().unwrap();
    let mut object_pixels = 0;
    let mut sum = 0.0f64;
    for (i, p) in images.left.pixels().iter().enumerate() {
        let sigma = variance.pixels()[i].sqrt();
        for c in p {
            assert!(
                (c - 1.0).abs() <= 5.0 * sigma + 2e-3,
                "{what}: pixel {i} = {p:?}, σ = {sigma}"
            );
        }
        if images.depth.pixels()[i].is_finite() {
            object_pixels += 1;
            sum += p[1] as f64;
        }
    }
    assert!(
        object_pixels > 100,
        "{what}: object covers {object_pixels} px"
    );
    let mean = sum / object_pixels as f64;
    assert!((mean - 1.0).abs() < 0.005, "{what}: mean radiance {mean}");
}

#[test]
fn white_furnace_sphere_at_every_bounce_limit() {
    for bounces in [8, 16] {
        let images = furnace(
            Shape::Sphere {
                radius: 1.0,
                segments: Some(64),
            },
            bounces,
        );
        assert_furnace(&images, &format!("sphere, {bounces} bounces"));
    }
}

#[test]
fn white_furnace_torus_with_interreflections() {
    // A torus sees itself, so light bounces between its parts: only a correct estimator with
    // unbiased Russian roulette keeps the furnace invisible.
    let images = furnace(
        Shape::Torus {
            major_radius: 1.0,
            minor_radius: 0.6,
            segments: Some(64),
        },
        64,
    );
    assert_furnace(&images, "torus");
}

#[test]
fn furnace_detects_energy_loss_of_a_grey_object() {
    // The same test must fail for an albedo below one: the sphere then shows up darker.
    let scene = Scene {
        name: "grey".into(),
        camera: rig(32, 24, [0.0, 0.0, 4.0], [0.0, 0.0, 0.0]),
        objects: vec![Object {
            name: String::new(),
            shape: Shape::Sphere {
                radius: 1.0,
                segments: None,
            },
            material: Material::lambert([0.9; 3]),
            transform: Transform::default(),
        }],
        lights: vec![],
        environment: Environment::Constant { radiance: [1.0; 3] },
        portals: Vec::new(),
    };
    let images = render(&scene, &spp(32, 8)).unwrap();
    let object: Vec<f32> = images
        .left
        .pixels()
        .iter()
        .zip(images.depth.pixels())
        .filter(|(_, z)| z.is_finite())
        .map(|(p, _)| p[1])
        .collect();
    let mean = object.iter().sum::<f32>() / object.len() as f32;
    assert!((mean - 0.9).abs() < 0.005, "mean {mean}");
}

/// World point seen at pixel (x, y), from the ground-truth depth.
fn world_point(images: &Images, x: usize, y: usize) -> glam::Vec3 {
    let c = &images.calibration;
    let z = *images.depth.get(x, y) as f64;
    let cam = glam::DVec3::new(
        (x as f64 + 0.5 - c.cx) * z / c.focal_px,
        -(y as f64 + 0.5 - c.cy) * z / c.focal_px,
        -z,
    );
    let m = glam::Mat4::from_cols_array(&images.camera_to_world);
    m.transform_point3(cam.as_vec3())
}

#[test]
fn point_like_sphere_light_over_a_diffuse_plane_matches_inverse_square_law() {
    let (radius, radiance, albedo) = (0.01f32, 2.0e4f32, 0.5f32);
    let light_pos = glam::Vec3::new(0.0, 2.0, 0.0);
    let scene = Scene {
        name: "point light".into(),
        camera: rig(48, 36, [0.0, 2.5, 1.5], [0.0, 0.0, -0.5]),
        objects: vec![Object {
            name: "floor".into(),
            shape: Shape::Plane { size: [40.0, 40.0] },
            material: Material::lambert([albedo; 3]),
            transform: Transform::default(),
        }],
        lights: vec![Light::Sphere {
            center: light_pos.to_array(),
            radius,
            radiance: [radiance; 3],
        }],
        environment: Environment::Black,
        portals: Vec::new(),
    };
    let images = render(&scene, &spp(32, 8)).unwrap();
    let variance = images.variance.as_ref().unwrap();
    let intensity = std::f32::consts::PI * radius * radius * radiance;
    let mut checked = 0;
    for y in (0..36).step_by(5) {
        for x in (0..48).step_by(5) {
            if !images.depth.get(x, y).is_finite() {
                continue;
            }
            // The pixel averages over its footprint: average the analytic value over 8×8 points.
            let mut expected = 0.0;
            for k in 0..64 {
                let (a, b) = ((k % 8) as f64 + 0.5, (k / 8) as f64 + 0.5);
                let Some(p) = floor_point(&images, x as f64 + a / 8.0, y as f64 + b / 8.0) else {
                    continue;
                };
                let to_light = light_pos - p;
                let r2 = to_light.length_squared();
                let cos = to_light.normalize().y;
                // Exact for a sphere wholly above the plane: E = I cos θ / r².
                expected += albedo / std::f32::consts::PI * intensity * cos / r2 / 64.0;
            }
            let got = images.left.get(x, y)[0];
            // Where the light varies strongly across the pixel, jittered samples are noisy: the
            // render's own noise estimate says where the 2 % comparison is meaningful.
            if variance.get(x, y).sqrt() > 0.004 * got {
                continue;
            }
            assert!(
                (got / expected - 1.0).abs() < 0.02,
                "pixel ({x}, {y}): {got} vs E·ρ/π = {expected}"
            );
            assert_eq!(*images.shadow[0].get(x, y), 1.0);
            checked += 1;
        }
    }
    assert!(checked > 30, "only {checked} floor pixels");
    // The light itself, straight above the floor, is not in view; the records say what it is.
    assert_eq!(images.lights[0].kind, "sphere");
    let i = images.lights[0].intensity.unwrap()[0];
    assert!((i / intensity - 1.0).abs() < 1e-6);
}

/// Where the ray through image point (px, py) meets the plane y = 0.
fn floor_point(images: &Images, px: f64, py: f64) -> Option<glam::Vec3> {
    let c = &images.calibration;
    let m = glam::DMat4::from_cols_array(&images.camera_to_world.map(f64::from));
    let d = m.transform_vector3(glam::DVec3::new(
        (px - c.cx) / c.focal_px,
        -(py - c.cy) / c.focal_px,
        -1.0,
    ));
    let o = m.transform_point3(glam::DVec3::ZERO);
    let t = -o.y / d.y;
    (t > 0.0).then(|| (o + d * t).as_vec3())
}

fn looking_down_minus_z(width: u32, height: u32) -> CameraRig {
    rig(width, height, [0.0, 0.0, 0.0], [0.0, 0.0, -1.0])
}

#[test]
fn disparity_of_a_fronto_parallel_plane_is_exactly_f_b_over_z() {
    let z = 2.0f32;
    let scene = Scene {
        name: "wall".into(),
        camera: looking_down_minus_z(64, 48),
        objects: vec![Object {
            name: "wall".into(),
            shape: Shape::Plane { size: [20.0, 20.0] },
            material: Material::lambert([0.5; 3]),
            transform: Transform {
                translation: [0.0, 0.0, -z],
                rotation_deg: [0.0, 90.0, 0.0],
                scale: [1.0; 3],
            },
        }],
        lights: vec![],
        environment: Environment::Constant { radiance: [1.0; 3] },
        portals: Vec::new(),
    };
    let images = render(&scene, &spp(1, 1)).unwrap();
    let c = images.calibration;
    let expected = (c.focal_px * c.baseline_m / z as f64) as f32;
    for y in 0..48 {
        for x in 0..64 {
            let d = *images.disparity.get(x, y);
            assert!(
                (d - expected).abs() <= expected * 1e-6,
                "({x}, {y}): {d} vs {expected}"
            );
            assert!((images.depth.get(x, y) - z).abs() <= z * 1e-6);
            // Seen by the right camera unless it falls off its left edge.
            let expected_mask = if (x as f32 + 0.5) < d { 128 } else { 255 };
            assert_eq!(
                *images.nonocc.get(x, y),
                expected_mask,
                "mask at ({x}, {y})"
            );
            let n = images.normals.get(x, y);
            assert!((n[2] - 1.0).abs() < 1e-5, "normal {n:?}");
        }
    }
}

#[test]
fn disparity_of_a_slanted_plane_matches_the_analytic_value_per_pixel() {
    // The plane z = −3 + x/4 + y/8 (camera frame = world), built from exactly representable corners.
    let plane_z = |x: f32, y: f32| -3.0 + x / 4.0 + y / 8.0;
    let corners = [(-8.0, -8.0), (8.0, -8.0), (8.0, 8.0), (-8.0, 8.0)];
    let scene = Scene {
        name: "slanted".into(),
        camera: looking_down_minus_z(48, 40),
        objects: vec![Object {
            name: "slanted".into(),
            shape: Shape::Mesh {
                positions: corners.map(|(x, y)| [x, y, plane_z(x, y)]).to_vec(),
                indices: vec![[0, 1, 2], [0, 2, 3]],
                normals: None,
            },
            material: Material::lambert([0.5; 3]),
            transform: Transform::default(),
        }],
        lights: vec![],
        environment: Environment::Black,
        portals: Vec::new(),
    };
    let images = render(&scene, &spp(1, 1)).unwrap();
    let c = images.calibration;
    for y in 0..40 {
        for x in 0..48 {
            let dx = (x as f64 + 0.5 - c.cx) / c.focal_px;
            let dy = -(y as f64 + 0.5 - c.cy) / c.focal_px;
            // The ray t·(dx, dy, −1) meets −t = −3 + t·dx/4 + t·dy/8.
            let depth = 3.0 / (1.0 + dx / 4.0 + dy / 8.0);
            let expected = c.focal_px * c.baseline_m / depth;
            let d = *images.disparity.get(x, y) as f64;
            assert!(
                (d - expected).abs() < 1e-5 * expected,
                "({x}, {y}): {d} vs {expected}"
            );
        }
    }
}

fn penumbra_scene(light_size: f32) -> Scene {
    // Floor at y = 0, a long blocker at height 1 with its edge at x = 0.5, a square light of side
    // `light_size` at height 2 centred over x = 0: the penumbra is centred at x = 1 and, by similar
    // triangles, `light_size · 1 / (2 − 1)` wide.
    Scene {
        name: "penumbra".into(),
        camera: CameraRig {
            width: 128,
            height: 64,
            fov_x_deg: Some(40.0),
            focal_px: None,
            baseline_m: 0.058,
            position: [1.0, 4.0, 0.0],
            look_at: [1.0, 0.0, 0.0],
            up: [0.0, 0.0, -1.0],
        },
        objects: vec![
            Object {
                name: "floor".into(),
                shape: Shape::Plane { size: [10.0, 10.0] },
                material: Material::lambert([0.5; 3]),
                transform: Transform::default(),
            },
            Object {
                name: "blocker".into(),
                shape: Shape::Box {
                    size: [1.0, 0.01, 4.0],
                },
                material: Material::lambert([0.5; 3]),
                transform: Transform::at(0.0, 1.0, 0.0),
            },
        ],
        lights: vec![Light::Rect {
            center: [0.0, 2.0, 0.0],
            edge_u: [light_size, 0.0, 0.0],
            edge_v: [0.0, 0.0, light_size],
            radiance: [10.0; 3],
        }],
        environment: Environment::Black,
        portals: Vec::new(),
    }
}

/// Penumbra width along the image row through z = 0: for a linear ramp m from 0 to 1 over a width
/// W, ∫ m (1 − m) dx = W / 6.
fn penumbra_width(images: &Images) -> f64 {
    let c = images.calibration;
    let y = images.shadow[0].height() / 2;
    let row = images.shadow[0].row(y);
    // Only floor pixels (the blocker's top is 3 m from the camera, the floor 4 m).
    row.iter()
        .zip(images.depth.row(y))
        .filter(|(_, z)| **z > 3.5)
        .map(|(m, z)| 6.0 * (*m as f64) * (1.0 - *m as f64) * *z as f64 / c.focal_px)
        .sum()
}

#[test]
fn penumbra_width_follows_the_light_size() {
    let mut widths = Vec::new();
    for size in [0.15f32, 0.45] {
        let images = render(&penumbra_scene(size), &spp(64, 1)).unwrap();
        let w = penumbra_width(&images);
        assert!(
            (w / size as f64 - 1.0).abs() < 0.2,
            "light {size} m: penumbra {w} m, expected {size} m"
        );
        // Umbra under the blocker, full light beyond the penumbra.
        let row = images.shadow[0].row(32);
        assert!(row.contains(&0.0) && row.contains(&1.0));
        widths.push(w);
    }
    assert!(widths[1] > 2.0 * widths[0], "{widths:?}");
}

#[test]
fn images_do_not_depend_on_the_thread_count() {
    let scene = builtin("two-lights").unwrap();
    let options = RenderOptions {
        width: Some(40),
        samples: SampleBudget::PerPixel(2),
        seed: 11,
        ..RenderOptions::default()
    };
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| render(&scene, &options).unwrap())
    };
    let (one, two) = (run(1), run(2));
    assert_eq!(one.left, two.left);
    assert_eq!(one.right, two.right);
    assert_eq!(one.shadow, two.shadow);
    assert_eq!(one.stats.rays, two.stats.rays);
    // And the seed matters.
    let other = render(
        &scene,
        &RenderOptions {
            seed: 12,
            ..options
        },
    )
    .unwrap();
    assert_ne!(one.left, other.left);
}

#[test]
fn composite_equals_background_outside_the_objects_influence() {
    // The light stands to the left and behind, so the shadow falls towards the camera, in view.
    let light = glam::Vec3::new(-1.2, 1.6, -1.0);
    let scene = Scene {
        name: "composite".into(),
        camera: rig(64, 48, [0.0, 2.0, 3.0], [0.0, 0.0, 0.0]),
        objects: vec![Object {
            name: "floor".into(),
            shape: Shape::Plane { size: [20.0, 20.0] },
            material: Material::diffuse([0.6; 3]),
            transform: Transform::default(),
        }],
        lights: vec![Light::Sphere {
            center: light.to_array(),
            radius: 0.02,
            radiance: [5000.0; 3],
        }],
        environment: Environment::Black,
        portals: Vec::new(),
    };
    let sphere = insert_shape("sphere", [0.3, 0.0, 0.0], 2.0, 0.0).unwrap();
    let centre = glam::Vec3::new(0.3, 0.2, 0.0);
    let radius = 0.2;
    let result = render_composite(&scene, &[sphere], &spp(8, 1)).unwrap();
    let geometry = render(&scene, &spp(1, 1)).unwrap();
    let (mut outside, mut umbra) = (0, 0);
    for y in 0..48 {
        for x in 0..64 {
            let mask = *result.mask.get(x, y);
            let ratio = result.ratio.get(x, y)[0];
            if mask > 0.0 || !geometry.depth.get(x, y).is_finite() {
                continue;
            }
            // Distance from the sphere's centre to the segment floor point → light.
            let p = world_point(&geometry, x, y);
            let seg = light - p;
            let t = ((centre - p).dot(seg) / seg.length_squared()).clamp(0.0, 1.0);
            let miss = (p + seg * t - centre).length();
            if miss > radius + 0.05 {
                assert_eq!(ratio, 1.0, "({x}, {y}) outside the shadow: ratio {ratio}");
                outside += 1;
            } else if miss < radius - 0.05 {
                assert!(ratio < 0.05, "({x}, {y}) in the umbra: ratio {ratio}");
                umbra += 1;
            }
        }
    }
    assert!(
        outside > 1000 && umbra > 10,
        "outside {outside}, umbra {umbra}"
    );
    assert!(result.mask.pixels().contains(&1.0));
}

#[test]
fn composite_with_indirect_light_stays_near_one_far_away() {
    let scene = builtin("room").unwrap();
    let options = RenderOptions {
        width: Some(48),
        samples: SampleBudget::PerPixel(8),
        ..RenderOptions::default()
    };
    let torus = insert_shape("torus", [-1.2, 0.0, -1.0], 1.0, 0.0).unwrap();
    let result = render_composite(&scene, &[torus], &options).unwrap();
    // Far from the object (the right half of the image), indirect light changes by little.
    let (w, h) = (result.ratio.width(), result.ratio.height());
    let mut sum = 0.0;
    let mut n = 0;
    for y in 0..h {
        for x in w * 3 / 4..w {
            sum += result.ratio.get(x, y)[1] as f64;
            n += 1;
        }
    }
    let mean = sum / n as f64;
    assert!((mean - 1.0).abs() < 0.02, "mean ratio far away {mean}");
}

#[test]
fn middlebury_layout_round_trips() {
    let images = render(
        &builtin("room").unwrap(),
        &RenderOptions {
            width: Some(32),
            samples: SampleBudget::PerPixel(2),
            ..RenderOptions::default()
        },
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    images.write_middlebury_layout(dir.path()).unwrap();
    let calib = StereoCalibration::load_middlebury(dir.path().join("calib.txt")).unwrap();
    assert!((calib.focal_px - images.calibration.focal_px).abs() < 1e-9);
    assert!((calib.baseline_m - 0.058).abs() < 1e-12);
    assert_eq!(calib.doffs, 0.0);
    let max_d = images
        .disparity
        .pixels()
        .iter()
        .copied()
        .fold(0.0f32, f32::max);
    assert!(calib.max_disparity.unwrap() as f32 >= max_d);
    // The calibration handed out in memory says what the file says, search range included.
    assert_eq!(images.calibration.max_disparity, calib.max_disparity);
    let limits = crate::image::ImageLimits::default();
    let disp = crate::image::Raster::read_pfm(dir.path().join("disp0GT.pfm"), &limits).unwrap();
    assert_eq!(disp.width(), 32);
    for (a, b) in disp.pixels().iter().zip(images.disparity.pixels()) {
        assert!(a == b || (a.is_nan() && b.is_nan()));
    }
    for name in [
        "im0.png",
        "im1.png",
        "mask0nocc.png",
        "depth0GT.pfm",
        "normals0GT.exr",
        "shadow0GT.exr",
        "lights.json",
        "environment.exr",
        "scene.json",
    ] {
        assert!(dir.path().join(name).is_file(), "{name} missing");
    }
    let lights: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("lights.json")).unwrap())
            .unwrap();
    assert_eq!(lights["lights"][0]["type"], "rect");
    // The room is closed: every pixel has a surface.
    assert!(images
        .depth
        .pixels()
        .iter()
        .all(|d| d.is_finite() && *d > 0.0));
    // scene.json reproduces the render's own description.
    let again = Scene::load(dir.path().join("scene.json")).unwrap();
    assert_eq!(again, images.scene);
}

#[test]
fn builtin_scenes_are_valid_and_round_trip_through_json() {
    for name in BUILTIN_SCENES {
        let scene = builtin(name).unwrap();
        assert_eq!(Scene::from_json(&scene.to_json()).unwrap(), scene);
    }
    assert!(matches!(builtin("nope"), Err(crate::Error::InvalidArgument(m)) if m.contains("room")));
}

#[test]
fn bad_input_is_rejected_with_a_named_reason() {
    let base = builtin("room").unwrap();
    let err = |s: &Scene| render(s, &spp(1, 1)).unwrap_err().to_string();
    let mut s = base.clone();
    s.objects[6].shape = Shape::Sphere {
        radius: -1.0,
        segments: None,
    };
    assert!(err(&s).contains("sphere radius"), "{}", err(&s));
    let mut s = base.clone();
    s.objects[0].material.roughness = f32::NAN;
    assert!(err(&s).contains("roughness"));
    let mut s = base.clone();
    s.camera.look_at = s.camera.position;
    assert!(err(&s).contains("look_at"));
    let mut s = base.clone();
    s.lights[0] = Light::Directional {
        direction: [0.0; 3],
        irradiance: [1.0; 3],
        angular_diameter_deg: 0.0,
    };
    assert!(err(&s).contains("direction"));
    let mut s = base.clone();
    s.environment = Environment::Equirect {
        path: "/nonexistent/sky.hdr".into(),
        scale: 1.0,
        rotation_deg: 0.0,
    };
    assert!(matches!(
        render(&s, &spp(1, 1)),
        Err(crate::Error::Io { .. })
    ));
    let mut s = base.clone();
    s.objects.push(Object {
        name: "broken".into(),
        shape: Shape::Mesh {
            positions: vec![[0.0; 3]],
            indices: vec![[0, 1, 2]],
            normals: None,
        },
        material: Material::default(),
        transform: Transform::default(),
    });
    assert!(err(&s).contains("refers to vertex"));
    let mut s = base.clone();
    s.portals.push(Portal {
        center: [0.0, 1.0, 0.0],
        edge_u: [1.0, 0.0, 0.0],
        edge_v: [2.0, 0.0, 0.0],
    });
    assert!(err(&s).contains("portal 0: portal area"), "{}", err(&s));
    s.portals[0].edge_v = [0.0, f32::NAN, 1.0];
    assert!(err(&s).contains("portal 0: edge_v must be finite"));
    assert!(render(&base, &spp(0, 1)).is_err());
    assert!(render(
        &base,
        &RenderOptions {
            width: Some(0),
            ..RenderOptions::default()
        }
    )
    .is_err());
    assert!(matches!(
        Scene::from_json("{\"camera\": 3}"),
        Err(crate::Error::Format(_))
    ));
    assert!(insert_shape("teapot", [0.0; 3], 1.0, 0.0).is_err());
    assert!(insert_shape("sphere", [0.0; 3], 0.0, 0.0).is_err());
}

#[test]
fn extreme_but_legal_scenes_give_finite_images() {
    // Nothing at all: black, no NaN, no surface anywhere.
    let empty = Scene {
        name: "empty".into(),
        camera: rig(8, 6, [0.0; 3], [0.0, 0.0, -1.0]),
        objects: vec![],
        lights: vec![],
        environment: Environment::Black,
        portals: Vec::new(),
    };
    let images = render(&empty, &spp(2, 8)).unwrap();
    assert!(images.left.pixels().iter().all(|p| *p == [0.0; 3]));
    assert!(images.disparity.pixels().iter().all(|d| d.is_nan()));
    assert!(images.nonocc.pixels().iter().all(|m| *m == 0));
    // A sky-only view: every pixel is the sky's radiance in that direction.
    let mut sky = empty.clone();
    sky.environment = Environment::Constant {
        radiance: [0.25, 0.5, 1.0],
    };
    let images = render(&sky, &spp(1, 8)).unwrap();
    assert!(images.left.pixels().iter().all(|p| *p == [0.25, 0.5, 1.0]));
    // Tiny and huge objects, a mirror, a black metal, a 1×1 image, a sun of zero size.
    let mut odd = builtin("window").unwrap();
    odd.objects.push(Object {
        name: "speck".into(),
        shape: Shape::Sphere {
            radius: 1e-6,
            segments: Some(3),
        },
        material: Material {
            metallic: 1.0,
            roughness: 0.0,
            base_color: [0.0; 3],
            ..Material::default()
        },
        transform: Transform::at(0.0, 1.0, -1.0),
    });
    odd.objects.push(Object {
        name: "mirror".into(),
        shape: Shape::Box {
            size: [0.5, 0.5, 0.01],
        },
        material: Material {
            metallic: 1.0,
            roughness: 0.0,
            base_color: [0.95; 3],
            ..Material::default()
        },
        transform: Transform::at(0.5, 1.2, -3.0),
    });
    odd.objects.push(Object {
        name: "far away".into(),
        shape: Shape::Sphere {
            radius: 1e5,
            segments: None,
        },
        material: Material::default(),
        transform: Transform::at(0.0, 0.0, -1e6),
    });
    odd.lights.push(Light::Directional {
        direction: [0.1, -1.0, 0.0],
        irradiance: [1.0; 3],
        angular_diameter_deg: 0.0,
    });
    for (w, h) in [(1, 1), (24, 18)] {
        let images = render(
            &odd,
            &RenderOptions {
                width: Some(w),
                height: Some(h),
                samples: SampleBudget::PerPixel(2),
                ..RenderOptions::default()
            },
        )
        .unwrap();
        assert!(images
            .left
            .pixels()
            .iter()
            .flatten()
            .all(|c| c.is_finite() && *c >= 0.0));
        assert!(images
            .shadow
            .iter()
            .all(|s| s.pixels().iter().all(|v| (0.0..=1.0).contains(v))));
        assert!(images
            .variance
            .as_ref()
            .unwrap()
            .pixels()
            .iter()
            .all(|v| v.is_finite()));
    }
}

#[test]
fn a_time_budget_takes_at_least_one_sample() {
    let images = render(
        &builtin("room").unwrap(),
        &RenderOptions {
            width: Some(16),
            samples: SampleBudget::Time(std::time::Duration::from_millis(200)),
            ..RenderOptions::default()
        },
    )
    .unwrap();
    assert!(images.stats.samples_per_pixel >= 1);
    assert!(images.stats.rays > 0 && images.stats.rays_per_second > 0.0);
}

/// Mean linear luminance of a block of the left view and the variance of that mean (from the
/// render's own per-pixel variance of the mean).
fn block_luminance(images: &Images, x0: usize, y0: usize, size: usize) -> (f64, f64) {
    let variance = images.variance.as_ref().unwrap();
    let (mut sum, mut var) = (0.0f64, 0.0f64);
    for y in y0..y0 + size {
        for x in x0..x0 + size {
            sum += crate::image::rec709_luma(*images.left.get(x, y)) as f64;
            var += *variance.get(x, y) as f64;
        }
    }
    let n = (size * size) as f64;
    (sum / n, var / (n * n))
}

/// The window scene lit through its portal converges to the same image as without the portal
/// (block means agree within their noise, for the sun as a disc and as a delta light), with far
/// less noise at the same sample count. Double-counting the sunlit patch, or dropping one of the
/// three ways of finding it, shifts the block means by several of their standard errors.
#[test]
fn portals_lower_the_noise_without_changing_the_image() {
    for sun_diameter in [0.53f32, 0.0] {
        let mut with = builtin("window").unwrap();
        for light in &mut with.lights {
            if let Light::Directional {
                angular_diameter_deg,
                ..
            } = light
            {
                *angular_diameter_deg = sun_diameter;
            }
        }
        assert_eq!(with.portals.len(), 1);
        let without = Scene {
            portals: Vec::new(),
            ..with.clone()
        };
        let options = |samples| RenderOptions {
            width: Some(48),
            samples: SampleBudget::PerPixel(samples),
            seed: 5,
            ..RenderOptions::default()
        };
        let reference = render(&without, &options(768)).unwrap();
        let portal = render(&with, &options(96)).unwrap();
        let block = 12;
        let mut worst = 0.0f64;
        for y0 in (0..reference.left.height() - block + 1).step_by(block) {
            for x0 in (0..reference.left.width() - block + 1).step_by(block) {
                let (a, va) = block_luminance(&reference, x0, y0, block);
                let (b, vb) = block_luminance(&portal, x0, y0, block);
                let z = (a - b) / (va + vb).sqrt();
                worst = worst.max(z.abs());
                assert!(
                    z.abs() < 5.0,
                    "sun {sun_diameter}°: block at ({x0}, {y0}): {a} without, {b} with the \
                     portal (z = {z:.2})"
                );
            }
        }
        let (whole_a, whole_va) = block_luminance(&reference, 0, 0, 36);
        let (whole_b, whole_vb) = block_luminance(&portal, 0, 0, 36);
        let z = (whole_a - whole_b) / (whole_va + whole_vb).sqrt();
        assert!(
            z.abs() < 4.0,
            "sun {sun_diameter}°: left square {whole_a} vs {whole_b} (z = {z:.2})"
        );
        let cheap = render(&without, &options(96)).unwrap();
        let (noisy, clean) = (
            cheap.median_relative_noise().unwrap(),
            portal.median_relative_noise().unwrap(),
        );
        assert!(
            clean < 0.5 * noisy,
            "sun {sun_diameter}°: relative noise {clean} with the portal, {noisy} without"
        );
        eprintln!("sun {sun_diameter}°: worst block |z| {worst:.2}, noise {noisy:.3} → {clean:.3}");
    }
}

/// A wide directional light straight above a white Lambertian floor lights it to E/π exactly
/// (E = the irradiance on a surface facing the light; the disc is wholly above the horizon).
/// With an 80° disc a BRDF bounce finds the light often, so both strategies carry a large share:
/// a wrong weight on either one (say, none for the bounce from a primary vertex) moves the
/// result by several per cent.
#[test]
fn wide_directional_light_over_a_white_floor_gives_e_over_pi() {
    let irradiance = 3.0f32;
    let scene = Scene {
        name: "wide sun".into(),
        camera: rig(32, 24, [0.0, 1.5, 1.0], [0.0, 0.0, -0.5]),
        objects: vec![Object {
            name: "floor".into(),
            shape: Shape::Plane {
                size: [200.0, 200.0],
            },
            material: Material::lambert([1.0; 3]),
            transform: Transform::default(),
        }],
        lights: vec![Light::Directional {
            direction: [0.0, -1.0, 0.0],
            irradiance: [irradiance; 3],
            angular_diameter_deg: 80.0,
        }],
        environment: Environment::Black,
        portals: Vec::new(),
    };
    let images = render(&scene, &spp(64, 1)).unwrap();
    let expected = irradiance / std::f32::consts::PI;
    let (mut sum, mut n) = (0.0f64, 0);
    for (p, depth) in images.left.pixels().iter().zip(images.depth.pixels()) {
        if depth.is_finite() {
            sum += p[1] as f64;
            n += 1;
        }
    }
    assert!(n > 500, "{n} floor pixels");
    let mean = sum / n as f64;
    assert!(
        (mean / expected as f64 - 1.0).abs() < 0.01,
        "floor radiance {mean}, E/π = {expected}"
    );
}

/// Form factor from a surface element to a parallel rectangle `[x0, x1] × [z0, z1]` a distance
/// `c` away, the element at the origin of those coordinates (Howell's catalogue, B-3, one
/// rectangle per quadrant added with signs).
fn form_factor_to_parallel_rectangle(x0: f64, x1: f64, z0: f64, z1: f64, c: f64) -> f64 {
    // The rectangle from the foot point to (x, z), signed by its quadrant.
    let corner = |x: f64, z: f64| {
        let (a, b) = (x.abs() / c, z.abs() / c);
        let (ra, rb) = ((1.0 + a * a).sqrt(), (1.0 + b * b).sqrt());
        let f =
            (a / ra * (b / ra).atan() + b / rb * (a / rb).atan()) / (2.0 * std::f64::consts::PI);
        x.signum() * z.signum() * f
    };
    corner(x1, z1) - corner(x0, z1) - corner(x1, z0) + corner(x0, z0)
}

/// The beam strategy against a closed form. A sun straight overhead shines through a square
/// skylight onto a white floor; the camera looks up at the white ceiling around the skylight,
/// which the sun cannot reach, so each ceiling point's radiance (one bounce, nothing more) is
/// `ρ_c·ρ_f·E·F/π`, with `F` the form factor from the point to the sunlit square. The three
/// ways of finding that light (the beam through the skylight, a bounce to the floor and the
/// sun's sample there, two bounces into the sun's disc) must add up to it: under a small
/// skylight the beam carries nearly all of it, under a wide one the bounce competes.
///
/// It found that obvhs missed every shadow ray with a −0.0 direction component (towards a sun
/// exactly overhead, 35× too much light reached the ceiling); see `mesh::bvh::obvhs_ray`.
#[test]
fn sunlight_through_a_skylight_bounces_onto_the_ceiling_by_its_form_factor() {
    let (height, thickness, room) = (1.0f32, 0.002f32, 4.0f32);
    let (irradiance, albedo) = (10.0f32, 0.8f32);
    let slab = |centre: [f32; 3], size: [f32; 3]| Object {
        name: "ceiling".into(),
        shape: Shape::Box { size },
        material: Material::lambert([albedo; 3]),
        transform: Transform::at(centre[0], centre[1], centre[2]),
    };
    let y = height + 0.5 * thickness;
    // (half the skylight's side, the sun's angular diameter).
    let cases = [(0.15f32, 0.0f32), (0.15, 0.53), (0.6, 0.0), (0.6, 0.53)];
    for (half, sun_diameter) in cases {
        // The wide skylight needs a wide view to see ceiling around it.
        let fov = if half < 0.5 { 50.0 } else { 110.0 };
        let (side, rest) = (0.5 * room, 0.5 * room - half);
        let scene = Scene {
            name: "skylight".into(),
            camera: CameraRig {
                up: [0.0, 0.0, -1.0],
                fov_x_deg: Some(fov),
                ..rig(48, 36, [0.0, 0.05, 0.0], [0.0, 1.0, 0.0])
            },
            objects: vec![
                Object {
                    name: "floor".into(),
                    // Narrower than the ceiling, so that no slanted ray of the sun's disc
                    // reaches it past the ceiling's outer edge.
                    shape: Shape::Plane {
                        size: [room - 0.4, room - 0.4],
                    },
                    material: Material::lambert([albedo; 3]),
                    transform: Transform::default(),
                },
                slab([0.0, y, -(half + side) / 2.0], [room, thickness, rest]),
                slab([0.0, y, (half + side) / 2.0], [room, thickness, rest]),
                slab(
                    [-(half + side) / 2.0, y, 0.0],
                    [rest, thickness, 2.0 * half],
                ),
                slab([(half + side) / 2.0, y, 0.0], [rest, thickness, 2.0 * half]),
            ],
            lights: vec![Light::Directional {
                direction: [0.0, -1.0, 0.0],
                irradiance: [irradiance; 3],
                angular_diameter_deg: sun_diameter,
            }],
            environment: Environment::Black,
            portals: vec![Portal {
                center: [0.0, height + thickness, 0.0],
                edge_u: [2.0 * half, 0.0, 0.0],
                edge_v: [0.0, 0.0, 2.0 * half],
            }],
        };
        let images = render(
            &scene,
            &RenderOptions {
                seed: 11,
                ..spp(256, 2)
            },
        )
        .unwrap();
        let variance = images.variance.as_ref().unwrap();
        let (mut rendered, mut expected, mut var, mut n) = (0.0f64, 0.0f64, 0.0f64, 0usize);
        let mut worst = 0.0f64;
        for py in 0..images.depth.height() {
            for px in 0..images.depth.width() {
                if !images.depth.get(px, py).is_finite() {
                    continue;
                }
                let p = world_point(&images, px, py);
                assert!((p.y - height).abs() < 1e-3, "pixel ({px}, {py}) sees {p}");
                // Pixels whose footprint may reach into the skylight are left out.
                if p.x.abs().max(p.z.abs()) < half + 0.03 {
                    continue;
                }
                let (x, zw) = (p.x as f64, p.z as f64);
                let h = half as f64;
                let f = form_factor_to_parallel_rectangle(
                    -h - x,
                    h - x,
                    -h - zw,
                    h - zw,
                    height as f64,
                );
                let want = (albedo * albedo * irradiance) as f64 * f / std::f64::consts::PI;
                let got = crate::image::rec709_luma(*images.left.get(px, py)) as f64;
                let sigma = (*variance.get(px, py) as f64).sqrt();
                worst = worst.max(((got - want) / sigma.max(1e-9)).abs());
                rendered += got;
                expected += want;
                var += *variance.get(px, py) as f64;
                n += 1;
            }
        }
        assert!(n > 500, "{n} ceiling pixels");
        let z = (rendered - expected) / var.sqrt();
        eprintln!(
            "skylight {half} m, sun {sun_diameter}°: ratio {:.4}, z {z:.2}, worst pixel |z| {worst:.2}",
            rendered / expected
        );
        assert!(
            (rendered / expected - 1.0).abs() < 0.01 && z.abs() < 4.0,
            "skylight {half} m, sun {sun_diameter}°: ceiling {rendered:.4} rendered, {expected:.4} by the form \
             factor (z = {z:.2}) over {n} pixels"
        );
        assert!(
            worst < 5.5,
            "skylight {half} m, sun {sun_diameter}°: worst pixel |z| {worst:.2}"
        );
    }
}
