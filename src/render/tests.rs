//! Renderer tests on synthetic scenes built in code: a floor (and a wall) as the scene mesh,
//! boxes and spheres as artefacts, lights from [`Light`]. Expected values are analytic.

use std::sync::OnceLock;

use glam::{Mat4, Vec3, Vec4};

use super::shapes::{cube, sphere};
use super::*;
use crate::artefact::{AlphaMode, ArtefactSet, Material};
use crate::camera::Camera;
use crate::image::Raster;
use crate::light::{CubeLevel, CubeMap, Light, LightKind, Sh9};
use crate::mesh::SceneMesh;

const W: u32 = 80;
const H: u32 = 60;

fn renderer() -> &'static Renderer {
    static R: OnceLock<Renderer> = OnceLock::new();
    R.get_or_init(|| {
        let gpu = GpuContext::new(&GpuOptions::default()).expect(
            "a GPU adapter is required for this test (CI installs mesa-vulkan-drivers for llvmpipe)",
        );
        Renderer::new(&gpu).unwrap()
    })
}

fn camera() -> Camera {
    Camera::from_fov(60.0, W, H).unwrap()
}

/// A quad grid from `origin` along `u` and `v` (n × n cells), normal `u × v`.
fn quad_mesh(origin: Vec3, u: Vec3, v: Vec3, n: usize) -> SceneMesh {
    let normal = u.cross(v).normalize();
    let mut m = SceneMesh::default();
    for j in 0..=n {
        for i in 0..=n {
            let (s, t) = (i as f32 / n as f32, j as f32 / n as f32);
            m.positions.push((origin + u * s + v * t).to_array());
            m.normals.push(normal.to_array());
            m.tangents.push([u.x, u.y, u.z, 1.0]);
            m.uvs.push([s, t]);
        }
    }
    for j in 0..n {
        for i in 0..n {
            let a = (j * (n + 1) + i) as u32;
            let b = a + 1;
            let c = a + (n + 1) as u32;
            let d = c + 1;
            m.indices.extend_from_slice(&[a, b, d, a, d, c]);
        }
    }
    m
}

/// Floor at y = −1 from x −3..3, z −1..−9, seen from above (normal +Y).
fn floor() -> SceneMesh {
    quad_mesh(
        Vec3::new(-3.0, -1.0, -1.0),
        Vec3::new(6.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, -8.0),
        8,
    )
}

fn merge(mut a: SceneMesh, b: SceneMesh) -> SceneMesh {
    let base = a.positions.len() as u32;
    a.positions.extend(b.positions);
    a.normals.extend(b.normals);
    a.tangents.extend(b.tangents);
    a.uvs.extend(b.uvs);
    a.indices.extend(b.indices.iter().map(|i| i + base));
    a
}

fn diffuse(rgb: [f32; 3]) -> Material {
    Material {
        base_color_factor: Vec4::new(rgb[0], rgb[1], rgb[2], 1.0),
        metallic_factor: 0.0,
        roughness_factor: 1.0,
        ..Material::default()
    }
}

struct Scene {
    photo: Raster<[f32; 3]>,
    camera: Camera,
    mesh: Option<SceneMesh>,
    set: ArtefactSet,
    lights: Vec<Light>,
    sh: Sh9,
    mask: Option<Raster<f32>>,
}

impl Scene {
    fn new(mesh: Option<SceneMesh>) -> Scene {
        Scene {
            photo: Raster::filled(W as usize, H as usize, [0.5; 3]),
            camera: camera(),
            mesh,
            set: ArtefactSet::new(),
            lights: Vec::new(),
            sh: Sh9::default(),
            mask: None,
        }
    }

    fn render(&self, options: &RenderOptions) -> Composite {
        self.try_render(options, None).unwrap()
    }

    fn try_render(
        &self,
        options: &RenderOptions,
        env: Option<SpecularEnvironment<'_>>,
    ) -> crate::Result<Composite> {
        self.render_on(renderer(), options, env)
    }

    fn render_on(
        &self,
        renderer: &Renderer,
        options: &RenderOptions,
        env: Option<SpecularEnvironment<'_>>,
    ) -> crate::Result<Composite> {
        let out = renderer.render(
            &RenderInputs {
                photo: &self.photo,
                camera: &self.camera,
                scene_mesh: self.mesh.as_ref(),
                artefacts: &self.set,
                lights: &self.lights,
                sh9: &self.sh,
                specular: env,
                photo_shadow: self.mask.as_ref(),
            },
            options,
        )?;
        assert_all_finite(&out);
        Ok(out)
    }

    fn pixel(&self, p: Vec3) -> (usize, usize) {
        let (uv, _) = self.camera.project(p).unwrap();
        (uv.x as usize, uv.y as usize)
    }
}

fn assert_all_finite(c: &Composite) {
    let ok = c
        .composite
        .pixels()
        .iter()
        .flatten()
        .all(|v| v.is_finite() && *v >= 0.0)
        && c.shadow_ratio
            .pixels()
            .iter()
            .flatten()
            .all(|v| v.is_finite() && (0.0..=1.0).contains(v))
        && c.mask
            .pixels()
            .iter()
            .all(|v| v.is_finite() && (0.0..=1.0).contains(v))
        && c.artefact_depth
            .pixels()
            .iter()
            .all(|v| v.is_finite() && *v >= 0.0)
        && c.artefact_layer
            .pixels()
            .iter()
            .flatten()
            .all(|v| v.is_finite());
    assert!(ok, "an output holds NaN, inf or an out-of-range value");
}

fn small(shadows: ShadowMode) -> RenderOptions {
    RenderOptions {
        shadows,
        shadow_map_size: 512,
        ..RenderOptions::default()
    }
}

/// A red box of side `side` standing on `floor` (at y = −1) centred at (0, ·, −4), lit by a
/// directional light travelling along `light`.
fn box_standing_on(floor: SceneMesh, side: f32, light: [f32; 3]) -> Scene {
    let mut s = Scene::new(Some(floor));
    s.set
        .add(
            cube(diffuse([0.8, 0.2, 0.2])),
            Mat4::from_translation(Vec3::new(0.0, -1.0 + 0.5 * side, -4.0))
                * Mat4::from_scale(Vec3::splat(side)),
        )
        .unwrap();
    s.lights.push(Light::directional(light, 0.5, [3.0; 3]));
    s
}

/// A 0.5 m box standing on the floor at (0, −1, −4), lit at 45° from the left: its shadow falls
/// to +x.
fn box_on_floor() -> Scene {
    box_standing_on(floor(), 0.5, [1.0, -1.0, 0.0])
}

/// Devices that cannot render into 32-bit floats (wgpu's OpenGL backend on llvmpipe) get 16-bit
/// shadow maps, shadow ratio and artefact depth. Forced here on any device, they must give the
/// same picture: the box, its shadow and its depth, in every shadow mode.
#[test]
fn sixteen_bit_targets_render_like_32_bit_ones() {
    let gpu = GpuContext::new(&GpuOptions::default()).unwrap();
    let half = Renderer::with_formats(
        &gpu.device,
        &gpu.queue,
        super::pipelines::TargetFormats::FLOAT16,
    )
    .unwrap();
    // A 30 m floor under a 0.3 m box: a directional map spans the whole floor's depth, so f16
    // distances alone (2 mm steps a few metres away) fall under the shadow test's bias, and lit
    // faces went black (found in review).
    let wide = || {
        let floor = quad_mesh(
            Vec3::new(-15.0, -1.0, -1.0),
            Vec3::new(30.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, -30.0),
            30,
        );
        box_standing_on(floor, 0.3, [1.0, -1.0, 0.3])
    };
    let mut cases = Vec::new();
    for mode in [ShadowMode::ThesisEsm, ShadowMode::Evsm, ShadowMode::Pcss] {
        cases.push((box_on_floor(), small(mode)));
        for size in [1024, 4096] {
            let options = RenderOptions {
                shadows: mode,
                shadow_map_size: size,
                ..RenderOptions::default()
            };
            cases.push((box_on_floor(), options));
            cases.push((wide(), options));
        }
    }
    for (s, options) in &cases {
        let (mode, size) = (options.shadows, options.shadow_map_size);
        let full = s.render(options);
        let reduced = s.render_on(&half, options, None).unwrap();
        // Depth comparisons may flip on a pixel or two of a silhouette or a shadow's edge.
        let (mut differing, mut sum) = (0usize, 0.0f64);
        for (a, b) in full
            .composite
            .pixels()
            .iter()
            .zip(reduced.composite.pixels())
        {
            let d = (0..3).map(|k| (a[k] - b[k]).abs()).fold(0.0f32, f32::max);
            differing += (d > 0.01) as usize;
            sum += d as f64;
        }
        let mean = sum / full.composite.pixels().len() as f64;
        assert!(
            differing <= 3 && mean < 0.001,
            "{mode:?}, {size}² maps: {differing} pixels differ by more than 0.01, {mean} on \
             average"
        );
        for (a, b) in full.mask.pixels().iter().zip(reduced.mask.pixels()) {
            assert!((a - b).abs() < 0.01, "{mode:?}: mask {a} vs {b}");
        }
        for (a, b) in full
            .artefact_depth
            .pixels()
            .iter()
            .zip(reduced.artefact_depth.pixels())
        {
            assert!(
                (a - b).abs() <= 1e-3 * a.abs(),
                "{mode:?}: artefact depth {a} vs {b}"
            );
        }
    }
}

#[test]
fn box_is_drawn_where_it_stands_and_its_shadow_darkens_the_floor_in_every_mode() {
    let s = box_on_floor();
    let on_box = s.pixel(Vec3::new(0.0, -0.6, -3.75));
    let umbra = s.pixel(Vec3::new(0.55, -1.0, -4.0));
    let far = s.pixel(Vec3::new(-2.0, -1.0, -7.0));
    let in_front = s.pixel(Vec3::new(0.0, -1.0, -2.5));
    for mode in [ShadowMode::ThesisEsm, ShadowMode::Evsm, ShadowMode::Pcss] {
        let c = s.render(&small(mode));
        assert!(
            *c.mask.get(on_box.0, on_box.1) > 0.99,
            "{mode:?}: box missing"
        );
        assert!(*c.mask.get(far.0, far.1) == 0.0);
        let d = *c.artefact_depth.get(on_box.0, on_box.1);
        assert!((d - 3.75).abs() < 0.05, "{mode:?}: artefact depth {d}");
        let r = c.shadow_ratio.get(umbra.0, umbra.1)[0];
        assert!(r < 0.6, "{mode:?}: umbra ratio {r}");
        let r_far = c.shadow_ratio.get(far.0, far.1)[0];
        assert!(r_far > 0.99, "{mode:?}: far ratio {r_far}");
        let r_front = c.shadow_ratio.get(in_front.0, in_front.1)[0];
        assert!(
            r_front > 0.99,
            "{mode:?}: lit floor in front of the box {r_front}"
        );
        let photo = s.photo.get(umbra.0, umbra.1)[0];
        assert!((c.composite.get(umbra.0, umbra.1)[0] - photo * r).abs() < 1e-4);
        assert!(c
            .records
            .iter()
            .any(|r| r.stage == "render.light[0].shadow_map" && r.computed));
    }
    let off = s.render(&small(ShadowMode::Off));
    assert!(
        off.shadow_ratio.get(umbra.0, umbra.1)[0] > 0.99,
        "shadow mode off casts no shadow"
    );
}

#[test]
fn photo_shadow_mask_prevents_darkening_twice() {
    let mut s = box_on_floor();
    s.sh = constant_sh(0.3);
    let umbra = s.pixel(Vec3::new(0.55, -1.0, -4.0));
    let free = s
        .render(&small(ShadowMode::Pcss))
        .shadow_ratio
        .get(umbra.0, umbra.1)[0];
    s.mask = Some(Raster::filled(W as usize, H as usize, 1.0));
    let masked = s
        .render(&small(ShadowMode::Pcss))
        .shadow_ratio
        .get(umbra.0, umbra.1)[0];
    assert!(free < 0.7, "without a mask the shadow darkens: {free}");
    // Only the (small) ambient occlusion of the box remains.
    assert!(masked > 0.85, "already in shadow in the photo: {masked}");
    s.mask = Some(Raster::filled(W as usize + 1, H as usize, 1.0));
    assert!(matches!(
        s.try_render(&small(ShadowMode::Pcss), None),
        Err(crate::Error::SizeMismatch(_))
    ));
}

#[test]
fn artefact_behind_a_wall_is_hidden_up_to_the_walls_edge() {
    // A wall at z = −3 covering x < 0 (normal +Z), the box 2 m behind it straddling x = 0.
    let wall = quad_mesh(
        Vec3::new(-3.0, -1.0, -3.0),
        Vec3::new(3.0, 0.0, 0.0),
        Vec3::new(0.0, 3.0, 0.0),
        4,
    );
    let mut s = Scene::new(Some(merge(floor(), wall)));
    s.set
        .add(
            cube(diffuse([0.2, 0.8, 0.2])),
            Mat4::from_translation(Vec3::new(0.0, -0.5, -5.0)) * Mat4::from_scale(Vec3::splat(1.0)),
        )
        .unwrap();
    s.lights
        .push(Light::directional([0.0, -1.0, -0.2], 0.5, [3.0; 3]));
    let c = s.render(&small(ShadowMode::ThesisEsm));
    // The wall's edge x = 0 projects to u = cx = 40: columns < 40 lie wholly behind the wall.
    let y = s.pixel(Vec3::new(0.0, -0.5, -5.0)).1;
    let edge = s.camera.cx as usize;
    for x in edge - 6..edge {
        assert_eq!(*c.mask.get(x, y), 0.0, "column {x} is behind the wall");
    }
    for x in edge..edge + 5 {
        assert!(
            *c.mask.get(x, y) > 0.99,
            "column {x} shows the box: {}",
            c.mask.get(x, y)
        );
    }
    // Without the wall the hidden columns show the box.
    s.mesh = Some(floor());
    let c = s.render(&small(ShadowMode::ThesisEsm));
    assert!(*c.mask.get(edge - 3, y) > 0.99);
}

/// The glTF BRDF (Appendix B) times irradiance and cosine, evaluated independently here.
fn gltf_radiance(n: Vec3, v: Vec3, l: Vec3, base: f32, metallic: f32, rough: f32, e: f32) -> f32 {
    let h = (l + v).normalize();
    let (nl, nv, nh, vh) = (
        n.dot(l).max(0.0),
        n.dot(v).max(1e-4),
        n.dot(h).max(0.0),
        v.dot(h).max(0.0),
    );
    let a = (rough * rough).max(1e-3);
    let a2 = a * a;
    let f0 = 0.04 * (1.0 - metallic) + base * metallic;
    let f = f0 + (1.0 - f0) * (1.0 - vh).powi(5);
    let k = nh * nh * (a2 - 1.0) + 1.0;
    let d = a2 / (std::f32::consts::PI * k * k);
    let vis = 1.0
        / ((nl + (a2 + (1.0 - a2) * nl * nl).sqrt()) * (nv + (a2 + (1.0 - a2) * nv * nv).sqrt()));
    let c_diff = base * (1.0 - metallic);
    ((1.0 - f) * c_diff / std::f32::consts::PI + f * d * vis) * e * nl
}

#[test]
fn lit_sphere_matches_the_analytic_brdf_and_thesis_mode_matches_lambert() {
    let mut s = Scene::new(None);
    let centre = Vec3::new(0.0, 0.0, -3.0);
    s.set
        .add(
            sphere(diffuse([0.6; 3])),
            Mat4::from_translation(centre) * Mat4::from_scale(Vec3::splat(0.8)),
        )
        .unwrap();
    let l = Vec3::new(0.3, 1.0, 0.6).normalize();
    s.lights
        .push(Light::directional((-l).to_array(), 0.0, [2.0; 3]));
    let pbr = s.render(&small(ShadowMode::Off));
    let thesis = s.render(&RenderOptions {
        shading: ShadingMode::Thesis,
        ..small(ShadowMode::Off)
    });
    let mut checked = 0;
    for (u, v) in [(40usize, 30usize), (44, 26), (36, 25), (42, 34), (47, 30)] {
        // Ray through the pixel centre, hit on the sphere.
        let d = s.camera.ray_direction(u as f32 + 0.5, v as f32 + 0.5);
        let b = d.dot(centre);
        let disc = b * b - centre.length_squared() + 0.64;
        assert!(disc > 0.0, "pixel ({u},{v}) misses the sphere");
        let p = d * (b - disc.sqrt());
        let n = (p - centre).normalize();
        let view = -d;
        if n.dot(l) <= 0.05 {
            continue;
        }
        let expected = gltf_radiance(n, view, l, 0.6, 0.0, 1.0, 2.0);
        let got = pbr.composite.get(u, v)[0];
        assert!(
            (got - expected).abs() < 0.03 * expected + 2e-3,
            "PBR ({u},{v}): {got} vs {expected}"
        );
        let lambert = 0.6 * 2.0 * n.dot(l) / std::f32::consts::PI;
        let got_t = thesis.composite.get(u, v)[0];
        assert!(
            (got_t - lambert).abs() < 0.03 * lambert + 2e-3,
            "thesis ({u},{v}): {got_t} vs {lambert}"
        );
        checked += 1;
    }
    assert!(checked >= 3);
}

fn constant_sh(radiance: f32) -> Sh9 {
    let mut sh = Sh9::default();
    sh.coefficients[0] = [radiance; 3];
    sh
}

#[test]
fn mirror_metal_reflects_the_prefiltered_environment() {
    // Constant environment radiance 0.7 and a DFG table of (A, B) = (1, 0): a white metal mirror
    // shows exactly the environment.
    let mut s = Scene::new(None);
    s.set
        .add(
            sphere(Material {
                base_color_factor: Vec4::ONE,
                metallic_factor: 1.0,
                roughness_factor: 0.0,
                ..Material::default()
            }),
            Mat4::from_translation(Vec3::new(0.0, 0.0, -3.0)),
        )
        .unwrap();
    let levels = (0..3)
        .map(|k| {
            let size = 4u32 >> k;
            CubeLevel {
                size,
                texels: vec![[0.7; 3]; 6 * (size * size) as usize],
            }
        })
        .collect();
    let cube = CubeMap { levels };
    let dfg = vec![[1.0f32, 0.0]; 16];
    let env = SpecularEnvironment {
        prefiltered: &cube,
        dfg: &dfg,
        dfg_size: 4,
    };
    let c = s.try_render(&small(ShadowMode::Off), Some(env)).unwrap();
    let got = c.composite.get(40, 30);
    assert!((got[0] - 0.7).abs() < 0.01, "{got:?}");
    assert!(c
        .records
        .iter()
        .any(|r| r.stage == "render.specular_environment" && r.computed));
    // A table of the wrong size is an error naming it.
    let bad = SpecularEnvironment { dfg_size: 5, ..env };
    let e = s
        .try_render(&small(ShadowMode::Off), Some(bad))
        .unwrap_err();
    assert!(e.to_string().contains("DFG"), "{e}");
}

#[test]
fn no_artefact_gives_the_photo_itself_without_gpu_work() {
    let s = Scene::new(Some(floor()));
    let c = s.render(&small(ShadowMode::ThesisEsm));
    assert_eq!(c.composite.pixels(), s.photo.pixels());
    assert!(c.records.iter().all(|r| !r.computed));
}

#[test]
fn wrong_sized_photo_is_an_error() {
    let mut s = box_on_floor();
    s.photo = Raster::filled(W as usize - 1, H as usize, [0.5; 3]);
    let e = s
        .try_render(&small(ShadowMode::ThesisEsm), None)
        .unwrap_err();
    assert!(matches!(e, crate::Error::SizeMismatch(_)), "{e}");
    assert!(e.to_string().contains("79x60"), "{e}");
}

#[test]
fn bad_options_are_errors_naming_the_option() {
    let s = box_on_floor();
    for (o, name) in [
        (
            RenderOptions {
                shadow_map_size: 100,
                ..small(ShadowMode::Pcss)
            },
            "shadow_map_size",
        ),
        (
            RenderOptions {
                filter_radius: 9,
                ..small(ShadowMode::Pcss)
            },
            "filter_radius",
        ),
        (
            RenderOptions {
                esm_exponent: f32::NAN,
                ..small(ShadowMode::Pcss)
            },
            "esm_exponent",
        ),
        (
            RenderOptions {
                evsm_exponents: [-1.0, 1.0],
                ..small(ShadowMode::Pcss)
            },
            "evsm_exponents",
        ),
    ] {
        let e = s.try_render(&o, None).unwrap_err();
        assert!(e.to_string().contains(name), "{e}");
    }
}

#[test]
fn exponents_at_and_beyond_the_overflow_limit_stay_finite() {
    let s = box_on_floor();
    let umbra = s.pixel(Vec3::new(0.55, -1.0, -4.0));
    let far = s.pixel(Vec3::new(-2.0, -1.0, -7.0));
    for c in [44.36f32, 88.73, 1e4, 1e30, f32::MAX] {
        for mode in [ShadowMode::ThesisEsm, ShadowMode::Evsm] {
            let out = s.render(&RenderOptions {
                esm_exponent: c,
                evsm_exponents: [c, c],
                filter_radius: 8,
                ..small(mode)
            });
            // assert_all_finite ran; the shadow is still there and the lit floor still lit.
            assert!(
                out.shadow_ratio.get(far.0, far.1)[0] > 0.99,
                "{mode:?} c={c}"
            );
            if mode == ShadowMode::Evsm {
                assert!(
                    out.shadow_ratio.get(umbra.0, umbra.1)[0] < 0.6,
                    "{mode:?} c={c}"
                );
            }
        }
    }
}

#[test]
fn many_lights_and_many_artefacts() {
    let mut s = Scene::new(Some(floor()));
    s.sh = constant_sh(0.2);
    let shared = cube(diffuse([0.5, 0.5, 0.9]));
    for i in 0..100 {
        let (x, z) = ((i % 10) as f32 * 0.5 - 2.25, -2.5 - (i / 10) as f32 * 0.5);
        s.set
            .add(
                shared.clone(),
                Mat4::from_translation(Vec3::new(x, -0.9, z)) * Mat4::from_scale(Vec3::splat(0.2)),
            )
            .unwrap();
    }
    for i in 0..16 {
        let a = i as f32 / 16.0 * std::f32::consts::TAU;
        let light = if i % 2 == 0 {
            Light::directional([a.cos(), -1.0, a.sin()], 1.0, [0.3; 3])
        } else {
            Light {
                kind: LightKind::Point,
                position: [2.0 * a.cos(), 1.0, -5.0 + 2.0 * a.sin()],
                size: 0.2,
                intensity: [0.5; 3],
                ..Light::directional([0.0, -1.0, 0.0], 0.0, [0.0; 3])
            }
        };
        s.lights.push(light);
    }
    let c = s.render(&small(ShadowMode::Pcss));
    let first = s.pixel(Vec3::new(-0.25, -0.85, -2.4));
    assert!(*c.mask.get(first.0, first.1) > 0.99);
    let shadowed = c
        .records
        .iter()
        .filter(|r| r.stage.ends_with(".shadow_map") && r.computed)
        .count();
    assert_eq!(shadowed, 16);
}

#[test]
fn extreme_materials_scales_and_placements_stay_finite() {
    let materials = [
        Material {
            roughness_factor: 0.0,
            metallic_factor: 0.0,
            ..Material::default()
        },
        Material {
            roughness_factor: 1.0,
            metallic_factor: 0.0,
            ..Material::default()
        },
        Material {
            base_color_factor: Vec4::new(0.0, 0.0, 0.0, 1.0),
            metallic_factor: 1.0,
            roughness_factor: 0.3,
            ..Material::default()
        },
        Material {
            alpha_mode: AlphaMode::Blend,
            base_color_factor: Vec4::new(1.0, 1.0, 1.0, 0.5),
            double_sided: true,
            ..Material::default()
        },
        Material {
            alpha_mode: AlphaMode::Mask { cutoff: 0.5 },
            base_color_factor: Vec4::new(1.0, 1.0, 1.0, 0.2),
            ..Material::default()
        },
    ];
    let centre = Vec3::new(0.0, -0.5, -3.0);
    for (i, m) in materials.into_iter().enumerate() {
        let mut s = Scene::new(Some(floor()));
        s.sh = constant_sh(0.2);
        s.lights
            .push(Light::directional([0.2, -1.0, -0.3], 1.0, [2.0; 3]));
        s.set
            .add(
                sphere(m),
                Mat4::from_translation(centre) * Mat4::from_scale(Vec3::splat(0.4)),
            )
            .unwrap();
        let c = s.render(&small(ShadowMode::ThesisEsm));
        let (u, v) = s.pixel(centre);
        let a = *c.mask.get(u, v);
        match i {
            // Front and back faces, each half opaque.
            3 => assert!((a - 0.75).abs() < 0.02, "blend alpha {a}"),
            4 => assert_eq!(a, 0.0, "masked away"),
            _ => assert!(a > 0.99),
        }
        if i == 2 {
            // Black metal without an environment reflects only the SH fallback × F0 = 0.
            assert!(
                c.composite.get(u, v)[0] < 1e-3,
                "{:?}",
                c.composite.get(u, v)
            );
        }
    }
    // Scales 1e-6 and 1e6, an artefact across the near plane, a light inside an artefact, and a
    // grazing light.
    let cases: Vec<(Mat4, Light)> = vec![
        (
            Mat4::from_translation(centre) * Mat4::from_scale(Vec3::splat(1e-6)),
            Light::directional([0.0, -1.0, 0.0], 1.0, [2.0; 3]),
        ),
        (
            Mat4::from_translation(Vec3::new(0.0, 0.0, -2e6)) * Mat4::from_scale(Vec3::splat(1e6)),
            Light::directional([0.0, -1.0, 0.0], 1.0, [2.0; 3]),
        ),
        // z from −0.5 to −0.005: the near plane (0.01) cuts its front face away.
        (
            Mat4::from_translation(Vec3::new(0.0, -0.35, -0.2525))
                * Mat4::from_scale(Vec3::splat(0.495)),
            Light::directional([0.0, -1.0, 0.0], 1.0, [2.0; 3]),
        ),
        (
            Mat4::from_translation(centre) * Mat4::from_scale(Vec3::splat(0.5)),
            Light {
                kind: LightKind::Point,
                position: centre.to_array(),
                size: 0.0,
                intensity: [5.0; 3],
                ..Light::directional([0.0, -1.0, 0.0], 0.0, [1.0; 3])
            },
        ),
        (
            Mat4::from_translation(centre) * Mat4::from_scale(Vec3::splat(0.5)),
            Light::directional([1.0, -0.002, 0.0], 0.5, [2.0; 3]),
        ),
    ];
    for (k, (transform, light)) in cases.into_iter().enumerate() {
        let mut s = Scene::new(Some(floor()));
        s.sh = constant_sh(0.2);
        s.lights.push(light);
        s.set.add(cube(diffuse([0.7; 3])), transform).unwrap();
        for mode in [ShadowMode::ThesisEsm, ShadowMode::Evsm, ShadowMode::Pcss] {
            let c = s.render(&small(mode));
            let centre_mask = *c.mask.get(40, 30);
            match k {
                0 => assert!(
                    c.mask.pixels().iter().all(|a| *a < 0.05),
                    "1e-6 m is sub-pixel"
                ),
                1 => assert!(
                    centre_mask > 0.99,
                    "1e6 m box fills the view: {centre_mask}"
                ),
                2 => {
                    // Its top face (y = −0.1) is seen from above behind the cut.
                    let p = s.pixel(Vec3::new(0.0, -0.1, -0.3));
                    assert!(
                        *c.mask.get(p.0, p.1) > 0.99,
                        "top face behind the near plane"
                    );
                }
                3 => {
                    // The light is inside a closed box: the floor around gets none of it.
                    let p = s.pixel(Vec3::new(1.0, -1.0, -3.0));
                    let r = c.shadow_ratio.get(p.0, p.1)[0];
                    assert!(
                        r < 0.5,
                        "{mode:?}: light inside the box still lights the floor: {r}"
                    );
                }
                _ => {}
            }
        }
    }
}

#[test]
fn renderer_works_on_a_hosts_device() {
    let gpu = GpuContext::new(&GpuOptions::default()).unwrap();
    let r = Renderer::from_device(&gpu.device, &gpu.queue).unwrap();
    let s = box_on_floor();
    let out = r
        .render(
            &RenderInputs {
                photo: &s.photo,
                camera: &s.camera,
                scene_mesh: s.mesh.as_ref(),
                artefacts: &s.set,
                lights: &s.lights,
                sh9: &s.sh,
                specular: None,
                photo_shadow: None,
            },
            &small(ShadowMode::Evsm),
        )
        .unwrap();
    assert_all_finite(&out);
    let p = s.pixel(Vec3::new(0.0, -0.6, -3.75));
    assert!(*out.mask.get(p.0, p.1) > 0.99);
}

/// With no scene mesh and one light, the shadow maps have a single layer (wgpu's OpenGL backend
/// took such a texture for a plain 2D one, and every point read as shadowed there under EVSM and
/// PCSS): a box above a slab must shadow the slab under it and nowhere else, in every mode.
#[test]
fn a_single_shadow_layer_shadows_only_under_the_caster() {
    let mut s = Scene::new(None);
    s.sh = constant_sh(0.2);
    s.lights
        .push(Light::directional([0.0, -1.0, 0.0], 0.5, [3.0; 3]));
    s.set
        .add(
            cube(diffuse([0.7; 3])),
            Mat4::from_translation(Vec3::new(0.0, -1.05, -3.0))
                * Mat4::from_scale(Vec3::new(3.0, 0.1, 3.0)),
        )
        .unwrap();
    s.set
        .add(
            cube(diffuse([0.7; 3])),
            Mat4::from_translation(Vec3::new(0.0, -0.5, -3.0)) * Mat4::from_scale(Vec3::splat(0.3)),
        )
        .unwrap();
    let under = s.pixel(Vec3::new(0.0, -1.0, -3.0));
    let beside = s.pixel(Vec3::new(0.8, -1.0, -2.8));
    for mode in [ShadowMode::ThesisEsm, ShadowMode::Evsm, ShadowMode::Pcss] {
        let c = s.render(&small(mode));
        assert!(
            c.records
                .iter()
                .any(|r| r.why.contains("1 views × 1 layers")),
            "{mode:?}: not one shadow layer: {:?}",
            c.records
        );
        let lit = c.artefact_layer.get(beside.0, beside.1)[0];
        let shadowed = c.artefact_layer.get(under.0, under.1)[0];
        // Lit: the light's 3 × 0.7/π plus the ambient, about 0.8.
        assert!(
            lit > 0.7,
            "{mode:?}: the slab beside the box is dark: {lit}"
        );
        // The thesis' ESM fades a shadow with its distance from the caster, so this one (35 cm
        // below it) is faint: 7 % darker on Vulkan; EVSM and PCSS are 80 % darker.
        assert!(
            shadowed < 0.97 * lit,
            "{mode:?}: no shadow under the box: {shadowed} against {lit}"
        );
    }
}

/// The renderer reads its lights, shadow views and occluding spheres from storage buffers in
/// the fragment shader. A device that allows none there (WebGL 2, many OpenGL ES 3.0 drivers)
/// cannot run it, and must be told so by a `Gpu` error when the renderer is made, not a panic.
#[test]
fn a_device_without_fragment_storage_buffers_is_a_gpu_error() {
    let (_instance, adapters) = super::context::find_adapters().expect("a GPU adapter");
    let adapter = &adapters[0];
    let limits = wgpu::Limits {
        max_storage_buffers_per_shader_stage: 0,
        ..adapter.limits()
    };
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        required_limits: limits,
        ..Default::default()
    }))
    .unwrap();
    match Renderer::from_device(&device, &queue) {
        Err(crate::Error::Gpu(message)) => {
            // wgpu's reason, naming the limit, not only "Validation Error"; on one line.
            assert!(
                message.contains("max_storage_buffers_per_shader_stage") && !message.contains('\n'),
                "{message}"
            )
        }
        other => panic!("expected a Gpu error, got {other:?}"),
    }
}
