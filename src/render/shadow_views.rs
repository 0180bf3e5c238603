//! Where each light's shadow map looks: an orthographic box fitted to the artefacts for a
//! directional light, a perspective frustum towards them (or a cube of six when they surround
//! the light) for point and area lights, and the decision to leave a light's map out.

use glam::{Mat4, Vec3};

use super::geometry::{corners, SceneGeometry};
use crate::artefact::Aabb;
use crate::light::{Light, LightKind};

/// One rendered shadow view (a map, or one cube face).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ShadowView {
    /// World → clip, reversed depth (near 1, far 0).
    pub view_proj: Mat4,
    /// Light position (perspective) or a point on the near plane (orthographic).
    pub origin: Vec3,
    /// Light direction of travel (orthographic; unused for perspective).
    pub axis: Vec3,
    pub orthographic: bool,
    /// Depth range of what the map holds, metres from `origin` (distance, or along `axis`).
    pub near: f32,
    pub far: f32,
    /// Shadow-map uv per metre: at unit distance for a perspective view (1 / (2 tan θ)), or
    /// everywhere for an orthographic one (1 / width).
    pub uv_per_metre: f32,
    /// Light radius in metres (perspective) or tangent of the half angular size (orthographic).
    pub light_extent: f32,
}

/// What to do about one light's shadows.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum LightShadowPlan {
    /// No map: the light is unshadowed, for the reason given.
    Skip(String),
    /// One view, or six for a cube; and why that shape.
    Views(Vec<ShadowView>, String),
}

/// World → view for an eye at `eye` looking along unit `dir` (right-handed, view looks down −z).
pub(crate) fn look_to(eye: Vec3, dir: Vec3, up: Vec3) -> Mat4 {
    let f = dir.normalize();
    let s = f.cross(up).normalize();
    let u = s.cross(f);
    Mat4::from_cols(
        glam::Vec4::new(s.x, u.x, -f.x, 0.0),
        glam::Vec4::new(s.y, u.y, -f.y, 0.0),
        glam::Vec4::new(s.z, u.z, -f.z, 0.0),
        glam::Vec4::new(-s.dot(eye), -u.dot(eye), f.dot(eye), 1.0),
    )
}

/// Square perspective projection with half-angle tangent `tan_half`, reversed depth: 1 at
/// `near`, 0 at `far`.
pub(crate) fn perspective_reversed(tan_half: f32, near: f32, far: f32) -> Mat4 {
    let s = 1.0 / tan_half;
    let a = near / (far - near);
    let b = near * far / (far - near);
    Mat4::from_cols(
        glam::Vec4::new(s, 0.0, 0.0, 0.0),
        glam::Vec4::new(0.0, s, 0.0, 0.0),
        glam::Vec4::new(0.0, 0.0, a, -1.0),
        glam::Vec4::new(0.0, 0.0, b, 0.0),
    )
}

/// Square orthographic projection of half width `half`, reversed depth: 1 at view z = 0, 0 at
/// view z = −`range`.
pub(crate) fn orthographic_reversed(half: f32, range: f32) -> Mat4 {
    Mat4::from_cols(
        glam::Vec4::new(1.0 / half, 0.0, 0.0, 0.0),
        glam::Vec4::new(0.0, 1.0 / half, 0.0, 0.0),
        glam::Vec4::new(0.0, 0.0, 1.0 / range, 0.0),
        glam::Vec4::new(0.0, 0.0, 1.0, 1.0),
    )
}

fn bounding_sphere(b: &Aabb) -> (Vec3, f32) {
    (b.center(), (b.size() * 0.5).length())
}

/// Extra fraction of a view's width kept around its content so filter taps at the edge still
/// read real depth.
fn border_fraction(map_size: u32, filter_radius: u32) -> f32 {
    (filter_radius as f32 + 2.0) * 2.0 / map_size as f32
}

/// Plans one light's shadow views.
pub(crate) fn plan(
    light: &Light,
    geometry: &SceneGeometry,
    map_size: u32,
    filter_radius: u32,
) -> LightShadowPlan {
    if light.intensity.iter().all(|c| *c <= 0.0) {
        return LightShadowPlan::Skip("zero intensity: nothing to shadow".into());
    }
    let Some(artefacts) = geometry.artefact_bounds else {
        return LightShadowPlan::Skip("no visible artefact".into());
    };
    if geometry.caster_bounds.is_none() && geometry.scene_bounds.is_none() {
        return LightShadowPlan::Skip(
            "nothing casts shadows (no casting artefact, no scene mesh)".into(),
        );
    }
    let Some(all) = geometry.all_bounds() else {
        return LightShadowPlan::Skip("nothing drawn".into());
    };
    let border = border_fraction(map_size, filter_radius);
    match light.kind {
        LightKind::Directional => {
            let forward = Vec3::from(light.direction).normalize_or(Vec3::NEG_Y);
            let up = if forward.y.abs() < 0.99 {
                Vec3::Y
            } else {
                Vec3::X
            };
            let view = look_to(Vec3::ZERO, forward, up);
            let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
            for c in corners(&artefacts) {
                let q = view.transform_point3(c);
                lo = lo.min(q);
                hi = hi.max(q);
            }
            // Depth spans every caster and receiver, not only the artefacts.
            let (mut zlo, mut zhi) = (f32::MAX, f32::MIN);
            for c in corners(&all) {
                let z = view.transform_point3(c).z;
                zlo = zlo.min(z);
                zhi = zhi.max(z);
            }
            let extent = (hi.x - lo.x).max(hi.y - lo.y).max(f32::MIN_POSITIVE);
            let half = 0.5 * extent * (1.0 + 2.0 * border);
            let (cx, cy) = (0.5 * (lo.x + hi.x), 0.5 * (lo.y + hi.y));
            // View space looks along −z: the nearest point to the light has the largest z.
            let depth = (zhi - zlo).max(extent * 1e-3);
            let pad = depth * 0.01;
            let near_z = zhi + pad;
            let range = depth + 2.0 * pad;
            let origin = view.inverse().transform_point3(Vec3::new(cx, cy, near_z));
            let light_view = look_to(origin, forward, up);
            let proj = orthographic_reversed(half, range);
            let tan_half = (0.5 * light.size.to_radians()).tan();
            LightShadowPlan::Views(
                vec![ShadowView {
                    view_proj: proj * light_view,
                    origin,
                    axis: forward,
                    orthographic: true,
                    near: 0.0,
                    far: range,
                    uv_per_metre: 1.0 / (2.0 * half),
                    light_extent: tan_half,
                }],
                "orthographic box fitted to the artefacts".into(),
            )
        }
        LightKind::Point | LightKind::Area => {
            let pos = Vec3::from(light.position);
            if light.kind == LightKind::Area {
                let axis = Vec3::from(light.direction).normalize_or_zero();
                if corners(&artefacts)
                    .iter()
                    .all(|c| (*c - pos).dot(axis) <= 0.0)
                {
                    return LightShadowPlan::Skip(
                        "the artefacts lie behind the area light's emitting side".into(),
                    );
                }
            }
            let far = corners(&all)
                .iter()
                .map(|c| (*c - pos).length())
                .fold(0.0f32, f32::max)
                * 1.01;
            let far = far.max(f32::MIN_POSITIVE * 1e6);
            // The depth buffer is reversed f32, so a tiny near plane costs no precision (except
            // on OpenGL, whose [−1, 1] remap keeps depth only to about 6·10⁻⁸: there, two
            // casters at about `d` from the light whose distances differ by less than about
            // 6 %·d²/far may be stored in the wrong order, which matters only for soft shadows'
            // blocker distance and for thin objects shadowing themselves). A light with a body
            // (a bulb seen in the photo sits a radius behind its own meshed front) clips what
            // lies within its body so that the lamp does not shadow its own light.
            let near = (far * 1e-6).max(light.body_reach().min(0.1 * far));
            let (centre, radius) = bounding_sphere(&artefacts);
            let to_centre = centre - pos;
            let dist = to_centre.length();
            let half_angle = if dist > radius * 1.05 {
                (radius / dist).asin()
            } else {
                f32::INFINITY
            };
            let radius_light = 0.5 * light.size;
            if half_angle < 60f32.to_radians() {
                let forward = to_centre / dist;
                let up = if forward.y.abs() < 0.99 {
                    Vec3::Y
                } else {
                    Vec3::X
                };
                let tan_half = half_angle.tan() * (1.0 + 2.0 * border);
                let fov = 2.0 * tan_half.atan();
                let view = look_to(pos, forward, up);
                let proj = perspective_reversed(tan_half, near, far);
                LightShadowPlan::Views(
                    vec![ShadowView {
                        view_proj: proj * view,
                        origin: pos,
                        axis: forward,
                        orthographic: false,
                        near,
                        far,
                        uv_per_metre: 1.0 / (2.0 * tan_half),
                        light_extent: radius_light,
                    }],
                    format!(
                        "perspective frustum of {:.1}° towards the artefacts",
                        fov.to_degrees()
                    ),
                )
            } else {
                // Faces in the GPU's cube order (+X −X +Y −Y +Z −Z); the shader picks a face by
                // the dominant axis, so each square frustum must be aligned with the cube.
                let faces = [
                    (Vec3::X, Vec3::Y),
                    (Vec3::NEG_X, Vec3::Y),
                    (Vec3::Y, Vec3::Z),
                    (Vec3::NEG_Y, Vec3::Z),
                    (Vec3::Z, Vec3::Y),
                    (Vec3::NEG_Z, Vec3::Y),
                ];
                let tan_half = 1.0 + 2.0 * border;
                let proj = perspective_reversed(tan_half, near, far);
                let views = faces
                    .iter()
                    .map(|&(f, up)| ShadowView {
                        view_proj: proj * look_to(pos, f, up),
                        origin: pos,
                        axis: f,
                        orthographic: false,
                        near,
                        far,
                        uv_per_metre: 1.0 / (2.0 * tan_half),
                        light_extent: radius_light,
                    })
                    .collect();
                LightShadowPlan::Views(
                    views,
                    "cube of six views: the artefacts surround the light or come too close".into(),
                )
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec4;

    fn geometry(artefacts: Aabb, scene: Option<Aabb>) -> SceneGeometry {
        SceneGeometry {
            artefact_bounds: Some(artefacts),
            caster_bounds: Some(artefacts),
            scene_bounds: scene,
            ..Default::default()
        }
    }

    fn project(v: &ShadowView, p: Vec3) -> Vec3 {
        let c = v.view_proj * p.extend(1.0);
        c.truncate() / c.w
    }

    #[test]
    fn directional_box_holds_the_artefacts_and_the_floor_depth() {
        let art = Aabb {
            min: Vec3::new(-0.1, 0.0, -2.1),
            max: Vec3::new(0.1, 0.2, -1.9),
        };
        let floor = Aabb {
            min: Vec3::new(-2.0, 0.0, -4.0),
            max: Vec3::new(2.0, 0.0, -1.0),
        };
        let light = Light::directional([0.3, -1.0, 0.1], 1.0, [1.0; 3]);
        let LightShadowPlan::Views(views, _) = plan(&light, &geometry(art, Some(floor)), 1024, 2)
        else {
            panic!("expected a view")
        };
        let v = views[0];
        for c in corners(&art) {
            let q = project(&v, c);
            assert!(
                q.x.abs() < 1.0 && q.y.abs() < 1.0 && (0.0..=1.0).contains(&q.z),
                "{q}"
            );
        }
        for c in corners(&floor) {
            let d = (c - v.origin).dot(v.axis);
            assert!(d > 0.0 && d < v.far, "{d} {}", v.far);
        }
        // Reversed depth: nearer the light is larger.
        let top = project(&v, Vec3::new(0.0, 0.2, -2.0)).z;
        let bottom = project(&v, Vec3::new(0.0, 0.0, -2.0)).z;
        assert!(top > bottom);
    }

    /// A unit box at the origin and a point light 5 m above it.
    fn box_under_a_point_light() -> (Aabb, Light) {
        let art = Aabb {
            min: Vec3::splat(-0.5),
            max: Vec3::splat(0.5),
        };
        let mut light = Light::directional([0.0, -1.0, 0.0], 0.0, [1.0; 3]);
        light.kind = LightKind::Point;
        light.position = [0.0, 5.0, 0.0];
        (art, light)
    }

    #[test]
    fn a_bulb_does_not_shadow_its_own_light() {
        // A bulb of diameter 0.3 m at 5 m: its own meshed surface (within its radius) lies in
        // front of the near plane; a bare point light keeps a near plane at ~0.
        let (art, mut light) = box_under_a_point_light();
        light.size = 0.3;
        let LightShadowPlan::Views(views, _) = plan(&light, &geometry(art, None), 512, 1) else {
            panic!()
        };
        assert!(
            views.iter().all(|v| v.near > 0.15 && v.near < 4.0),
            "{views:?}"
        );
        light.size = 0.0;
        let LightShadowPlan::Views(views, _) = plan(&light, &geometry(art, None), 512, 1) else {
            panic!()
        };
        assert!(views.iter().all(|v| v.near < 1e-3), "{views:?}");
    }

    #[test]
    fn point_light_far_away_gets_one_frustum_and_inside_gets_a_cube() {
        let (art, mut light) = box_under_a_point_light();
        let LightShadowPlan::Views(views, _) = plan(&light, &geometry(art, None), 512, 1) else {
            panic!()
        };
        assert_eq!(views.len(), 1);
        for c in corners(&art) {
            let q = project(&views[0], c);
            assert!(q.x.abs() < 1.0 && q.y.abs() < 1.0, "{q}");
            let clip = views[0].view_proj * c.extend(1.0);
            assert!(clip.w > 0.0);
        }
        light.position = [0.0, 0.0, 0.0];
        let LightShadowPlan::Views(views, _) = plan(&light, &geometry(art, None), 512, 1) else {
            panic!()
        };
        assert_eq!(views.len(), 6);
        // Each face's view sees the point on its own axis at its centre.
        for (i, axis) in [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z]
            .iter()
            .enumerate()
        {
            let q = views[i].view_proj * (*axis * 0.3).extend(1.0);
            let q = q / q.w;
            assert!(q.x.abs() < 1e-4 && q.y.abs() < 1e-4, "face {i}: {q}");
            let _ = Vec4::ZERO;
        }
    }

    #[test]
    fn skips_dark_lights_and_area_lights_facing_away() {
        let art = Aabb {
            min: Vec3::splat(-0.5),
            max: Vec3::splat(0.5),
        };
        let dark = Light::directional([0.0, -1.0, 0.0], 0.0, [0.0; 3]);
        assert!(matches!(
            plan(&dark, &geometry(art, None), 512, 1),
            LightShadowPlan::Skip(_)
        ));
        let mut area = Light::directional([0.0, 1.0, 0.0], 0.0, [1.0; 3]);
        area.kind = LightKind::Area;
        area.position = [0.0, 3.0, 0.0];
        area.size = 0.5;
        // Emits upwards, artefacts below.
        assert!(matches!(
            plan(&area, &geometry(art, None), 512, 1),
            LightShadowPlan::Skip(_)
        ));
        area.direction = [0.0, -1.0, 0.0];
        assert!(matches!(
            plan(&area, &geometry(art, None), 512, 1),
            LightShadowPlan::Views(..)
        ));
    }
}
