//! Questions about the reconstructed scene through the C ABI: support surfaces and the up
//! vector, picking a pixel, and placing an object.

use std::sync::Arc;

use glam::{Vec2, Vec3};

use super::boundary::{invalid, null_argument, optional_floats};
use super::scene::{plx_scene, with_scene, with_scene_state};
use crate::error::Status;
use crate::mesh::{PlaceOptions, Ray, SupportSurface, SurfaceKind};

/// Orientation of a surface relative to the estimated up (`plx_surface::kind`).
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum plx_surface_kind {
    /// Faces up within 10° (floor, table top): objects can stand on it.
    Horizontal = 0,
    /// Faces down within 10° (ceiling).
    Overhead = 1,
    /// Within 10° of vertical (wall).
    Vertical = 2,
    /// Anything else.
    Slanted = 3,
}

/// A planar surface of the scene, in the camera (= world) frame, metres.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct plx_surface {
    /// Unit normal, on the side facing the camera.
    pub normal: [f32; 3],
    /// Mean of the points on the surface.
    pub centroid: [f32; 3],
    /// Plane offset: points p on the plane satisfy dot(normal, p) = offset.
    pub offset: f32,
    /// Number of mesh vertices on the surface.
    pub inliers: u64,
    /// Flatness: root-mean-square distance of those points from the plane, metres.
    pub rms_m: f32,
    /// Area of the surface's extent (convex hull on the plane), square metres.
    pub area_m2: f32,
    /// A `plx_surface_kind` value.
    pub kind: u32,
}

fn c_surface(s: &SupportSurface) -> plx_surface {
    plx_surface {
        normal: s.normal.to_array(),
        centroid: s.centroid.to_array(),
        offset: s.offset,
        inliers: s.inliers as u64,
        rms_m: s.rms_m,
        area_m2: s.area_m2,
        kind: match s.kind {
            SurfaceKind::Horizontal => plx_surface_kind::Horizontal,
            SurfaceKind::Overhead => plx_surface_kind::Overhead,
            SurfaceKind::Vertical => plx_surface_kind::Vertical,
            SurfaceKind::Slanted => plx_surface_kind::Slanted,
        } as u32,
    }
}

/// The support surfaces (planes found in the scene mesh), largest first: `*count` of them at
/// `*out` (NULL when there are none), valid until the scene changes. When depth gives no mesh
/// (no valid depth, too small an image) there are none and the report warns why. Errors:
/// `NULL_ARGUMENT`; `NOT_AVAILABLE` without depth; as `plx_scene_depth` when stereo runs.
///
/// # Safety
/// `scene` is a live scene; `count` and `out` are writable.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_surfaces(
    scene: *mut plx_scene,
    count: *mut usize,
    out: *mut *const plx_surface,
) -> Status {
    with_scene_state(scene, |state| {
        if count.is_null() {
            return Err(null_argument("count"));
        }
        if out.is_null() {
            return Err(null_argument("out"));
        }
        let surfaces = state.scene.surfaces()?;
        let fresh = state
            .c_surfaces
            .as_ref()
            .is_none_or(|(from, _)| !Arc::ptr_eq(from, &surfaces));
        if fresh {
            let converted = surfaces.surfaces.iter().map(c_surface).collect();
            state.c_surfaces = Some((Arc::clone(&surfaces), converted));
        }
        let list = state.c_surfaces.as_ref().map_or(&[][..], |(_, v)| v);
        *count = list.len();
        *out = if list.is_empty() {
            std::ptr::null()
        } else {
            list.as_ptr()
        };
        Ok(())
    })
}

/// The gravity "up" (unit vector, camera frame) into `out[0..3]`: the host's
/// (`plx_scene_set_up`), else from the largest near-horizontal surfaces, else the camera's +Y.
/// Errors as `plx_scene_surfaces`.
///
/// # Safety
/// `scene` is a live scene; `out` points to 3 writable floats.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_up(scene: *mut plx_scene, out: *mut f32) -> Status {
    with_scene(scene, |scene| {
        if out.is_null() {
            return Err(null_argument("out"));
        }
        let up = scene.surfaces()?.up;
        std::ptr::copy_nonoverlapping(up.to_array().as_ptr(), out, 3);
        Ok(())
    })
}

/// Gives gravity "up" as `up[3]` (camera frame: +X right, +Y up, −Z forward; any length), e.g.
/// the gravity vector of an IMU or an AR runtime negated: surfaces are then classified against
/// it, placed objects stand upright along it and the lighting's "above" is it. NULL = back to
/// the up estimated from the planes. Setting the up it already has changes nothing. Errors:
/// `INVALID_ARGUMENT` for a non-finite or zero vector (the scene is unchanged).
///
/// # Safety
/// `scene` is a live scene; `up` is NULL or points to 3 readable floats.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_set_up(scene: *mut plx_scene, up: *const f32) -> Status {
    with_scene(scene, |scene| {
        match optional_floats::<3>(up) {
            Some(xyz) => scene.set_up(xyz)?,
            None => scene.clear_up(),
        }
        Ok(())
    })
}

/// What `plx_scene_pick` found.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct plx_hit {
    /// 1 when the pixel's ray hit the scene mesh; 0 when it did not (a hole in the depth, or a
    /// pixel outside the image), and then the other fields are 0.
    pub hit: u32,
    /// The 3D point, camera (= world) frame, metres.
    pub point: [f32; 3],
    /// Unit smooth surface normal there, facing the camera.
    pub normal: [f32; 3],
    /// Distance from the camera centre to the point, metres.
    pub distance: f32,
    /// Index of the triangle hit (into the indices of `plx_scene_mesh`, divided by 3).
    pub triangle: u32,
}

/// Picks the scene surface seen at image position (`x`, `y`) in continuous pixels (the centre of
/// pixel (i, j) is (i + 0.5, j + 0.5)). A miss is not an error: `out->hit` is 0. Errors:
/// `NULL_ARGUMENT`; `INVALID_ARGUMENT` for a non-finite position or when depth gives no mesh;
/// `NOT_AVAILABLE` without depth.
///
/// # Safety
/// `scene` is a live scene; `out` is writable.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_pick(
    scene: *mut plx_scene,
    x: f32,
    y: f32,
    out: *mut plx_hit,
) -> Status {
    with_scene(scene, |scene| {
        if out.is_null() {
            return Err(null_argument("out"));
        }
        *out = match scene.pick(Vec2::new(x, y))? {
            Some(h) => plx_hit {
                hit: 1,
                point: h.point.to_array(),
                normal: h.normal.to_array(),
                distance: h.t,
                triangle: h.triangle,
            },
            None => plx_hit {
                hit: 0,
                point: [0.0; 3],
                normal: [0.0; 3],
                distance: 0.0,
                triangle: 0,
            },
        };
        Ok(())
    })
}

/// Stands an object on the surface seen at image position (`x`, `y`) (continuous pixels) and
/// writes its model → world transform to `out_matrix` as 16 floats, **column-major** (OpenGL,
/// glTF, Unity's `Matrix4x4` element order m00, m10, m20, m30, m01, …; translation in elements
/// 12–14). The model is taken as glTF has it: +Y up, +Z its front, base centred at the origin,
/// largest side 1 unit; it is scaled to `size_m` metres, stood upright (gravity up on near-
/// horizontal surfaces, the surface normal elsewhere), its base on the surface (snapped to the
/// detected plane there; where stereo could not measure the depth and filled it, onto the plane
/// whose extent holds the pixel, if it passes within 25 % of the filled depth), and turned by
/// `yaw_deg` degrees about its up axis (0 = facing the camera). Errors: `NULL_ARGUMENT`;
/// `INVALID_ARGUMENT` for a size not finite and > 0, a non-finite yaw or position, no surface at
/// that pixel, or depth that gives no mesh;
/// `NOT_AVAILABLE` without depth.
///
/// # Safety
/// `scene` is a live scene; `out_matrix` points to 16 writable floats.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_place(
    scene: *mut plx_scene,
    x: f32,
    y: f32,
    size_m: f32,
    yaw_deg: f32,
    out_matrix: *mut f32,
) -> Status {
    with_scene(scene, |scene| {
        if out_matrix.is_null() {
            return Err(null_argument("out_matrix"));
        }
        let placed = scene.place(
            Vec2::new(x, y),
            size_m,
            yaw_deg.to_radians(),
            &PlaceOptions::default(),
        )?;
        let m = placed.transform.to_cols_array();
        std::ptr::copy_nonoverlapping(m.as_ptr(), out_matrix, 16);
        Ok(())
    })
}

/// `plx_scene_place` for the host's own ray (a controller, a gaze): `origin[3]` and `direction[3]`
/// (any length > 0) in the camera (= world) frame, metres; with `yaw_deg` 0 the object faces back
/// along the ray. Errors as `plx_scene_place`, and `INVALID_ARGUMENT` when the ray hits nothing.
///
/// # Safety
/// `scene` is a live scene; `origin` and `direction` point to 3 readable floats each,
/// `out_matrix` to 16 writable floats.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_place_on_ray(
    scene: *mut plx_scene,
    origin: *const f32,
    direction: *const f32,
    size_m: f32,
    yaw_deg: f32,
    out_matrix: *mut f32,
) -> Status {
    with_scene(scene, |scene| {
        if origin.is_null() {
            return Err(null_argument("origin"));
        }
        if direction.is_null() {
            return Err(null_argument("direction"));
        }
        if out_matrix.is_null() {
            return Err(null_argument("out_matrix"));
        }
        let read = |p: *const f32| Vec3::from_array(std::ptr::read_unaligned(p.cast::<[f32; 3]>()));
        let ray = Ray::new(read(origin), read(direction));
        if !(ray.origin.is_finite() && ray.direction.is_finite() && ray.direction != Vec3::ZERO) {
            return Err(invalid(
                "the ray's origin and direction must be finite, the direction non-zero",
            ));
        }
        let placed =
            scene.place_on_ray(&ray, size_m, yaw_deg.to_radians(), &PlaceOptions::default())?;
        let m = placed.transform.to_cols_array();
        std::ptr::copy_nonoverlapping(m.as_ptr(), out_matrix, 16);
        Ok(())
    })
}
