//! Placement: a model transform that stands an object on the scene surface under a pixel (or
//! under a host's own ray), upright, its base touching the surface, at a real size in metres.
//!
//! The object is taken in its own frame as glTF has it: +Y up, +Z its front, its base at `y = 0`
//! centred on the origin, and size 1 — or, with [`PlaceOptions::model_bounds`], any bounding box,
//! which is then moved so its bottom centre is the origin and scaled so its largest side is 1.
//! The ray's hit is snapped onto the detected support plane under it when there is one (its fitted
//! plane is more accurate than any single mesh triangle).
//!
//! ## Where the depth was filled
//! A stereo matcher measures only part of a noisy photo (a quarter of the pixels on the 16-spp
//! built-in renders) and fills the rest from the nearest measurements, which can be 15–20 % off
//! across a dark, textureless stretch of floor under a table (docs/reconstruction-eval.md, stop
//! 47). There the hit says little, and the plane whose image extent holds the pixel is the better
//! guess. Given the depth's confidence ([`PlacementScene::confidence`]), a hit on a pixel of
//! confidence 0 that no plane takes by the usual rule snaps onto the largest level, vertical or
//! overhead plane whose image extent holds the pixel and whose intersection with the ray lies within
//! [`PlaceOptions::unmeasured_snap_tolerance`] of the hit's distance (25 % by default; fills 15–20 %
//! off were measured). The price: an unmeasured pixel of a low object in front of a plane (within
//! a quarter of its distance) is taken for the plane, where its depth was a guess either way.
//! Measured depth keeps the usual rule: there the hit is what stands on the plane.

use glam::{Mat3, Mat4, Vec2, Vec3};

use super::bvh::{camera_ray, Bvh, Hit, Ray};
use super::filled::FilledDepth;
use super::surfaces::{SupportSurface, SurfaceKind, Surfaces};
use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::image::Raster;

/// Which way the placed object's +Y points.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Orientation {
    /// Gravity up on surfaces within `max_tilt_deg` of horizontal (a vase on a table), the surface
    /// normal elsewhere (a picture on a wall): the detected plane's at any slant, a lone mesh
    /// normal only within `max_tilt_deg` of vertical (a noisy stereo normal in between stands
    /// the object upright along gravity).
    Auto,
    /// Always the estimated gravity up.
    Gravity,
    /// Always the surface normal.
    SurfaceNormal,
}

/// Options of [`place`] and [`place_on_ray`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PlaceOptions {
    /// Default [`Orientation::Auto`].
    pub orientation: Orientation,
    /// For [`Orientation::Auto`]: surfaces tilted less than this from horizontal count as
    /// horizontal. Default 20°.
    pub max_tilt_deg: f32,
    /// Snap the hit onto a detected surface's plane when it lies within this fraction of its
    /// distance from the plane and faces the same way (within 20°). Default 0.03; 0 disables.
    pub snap_tolerance: f32,
    /// Where the depth under the hit was not measured (confidence 0, see the module
    /// documentation): snap onto a plane whose image extent holds the pixel when its intersection
    /// with the ray lies within this fraction of the hit's distance. Default 0.25; 0 disables.
    #[serde(default = "default_unmeasured_snap_tolerance")]
    pub unmeasured_snap_tolerance: f32,
    /// The object's bounding box in its own frame (min, max), when not already unit-sized with its
    /// base centred at the origin.
    pub model_bounds: Option<[Vec3; 2]>,
}

impl Default for PlaceOptions {
    fn default() -> Self {
        PlaceOptions {
            orientation: Orientation::Auto,
            max_tilt_deg: 20.0,
            snap_tolerance: 0.03,
            unmeasured_snap_tolerance: default_unmeasured_snap_tolerance(),
            model_bounds: None,
        }
    }
}

fn default_unmeasured_snap_tolerance() -> f32 {
    0.25
}

/// What an object is placed into: the scene mesh's ray queries, its camera and support surfaces,
/// and optionally the confidence of the depth the mesh was built from (the camera's size, in
/// [0, 1], 0 = filled or missing; see the module documentation).
#[derive(Clone, Copy)]
pub struct PlacementScene<'a> {
    /// Ray queries over the scene mesh.
    pub bvh: &'a Bvh,
    /// The camera the mesh was built for.
    pub camera: &'a Camera,
    /// The detected support surfaces.
    pub surfaces: &'a Surfaces,
    /// The depth's confidence; `None` treats every hit as measured. A map of another size than
    /// the camera's is not used.
    pub confidence: Option<&'a Raster<f32>>,
}

/// Where and how an object was placed.
#[derive(Debug, Clone, PartialEq)]
pub struct Placement {
    /// Model → world transform (column-major, glam/glTF/OpenGL convention).
    pub transform: Mat4,
    /// The point the object's base stands on, metres.
    pub base: Vec3,
    /// The object's up axis in the world (unit).
    pub up: Vec3,
    /// Normal of the surface under the object (unit).
    pub surface_normal: Vec3,
    /// Index into [`Surfaces::surfaces`] of the plane the hit was snapped to, if any.
    pub surface: Option<usize>,
    /// The mesh hit before snapping.
    pub hit: Hit,
}

/// Places an object of largest size `size_m` metres, turned by `yaw_rad` about its up axis (0 =
/// its front faces the camera), on the surface seen at image position `pixel`, or, where that
/// pixel falls into a crack of the mesh, at the nearest pixel within
/// [`PLACE_SEARCH_RADIUS_PX`] that shows a surface. Every hit counts as measured; see
/// [`PlacementScene::place`] for depth with a confidence.
///
/// # Errors
/// `InvalidArgument` for a size that is not finite and > 0, a non-finite yaw or pixel, bad
/// options, or no surface at or near the pixel (a hole in the depth).
pub fn place(
    bvh: &Bvh,
    camera: &Camera,
    surfaces: &Surfaces,
    pixel: Vec2,
    size_m: f32,
    yaw_rad: f32,
    options: &PlaceOptions,
) -> Result<Placement> {
    let scene = PlacementScene {
        bvh,
        camera,
        surfaces,
        confidence: None,
    };
    scene.place(pixel, size_m, yaw_rad, options)
}

/// How far (pixels) [`place`] looks around a pixel that shows no surface for one that does.
pub const PLACE_SEARCH_RADIUS_PX: u32 = 4;

/// [`place`] for a host's own ray (e.g. from a controller or a gaze), in the camera (= world)
/// frame. With `yaw_rad = 0` the object's front faces back along the ray. Every hit counts as
/// measured; see [`PlacementScene::place_on_ray`] for depth with a confidence.
///
/// # Errors
/// As [`place`]; `InvalidArgument` when the ray hits no surface or is not finite.
pub fn place_on_ray(
    bvh: &Bvh,
    surfaces: &Surfaces,
    ray: &Ray,
    size_m: f32,
    yaw_rad: f32,
    options: &PlaceOptions,
) -> Result<Placement> {
    stand_on_ray(bvh, surfaces, None, ray, size_m, yaw_rad, options)
}

impl PlacementScene<'_> {
    /// [`place`], with the depth's confidence: a hit where the depth was filled may snap onto the
    /// plane holding its pixel (module documentation).
    ///
    /// # Errors
    /// As [`place`].
    pub fn place(
        &self,
        pixel: Vec2,
        size_m: f32,
        yaw_rad: f32,
        options: &PlaceOptions,
    ) -> Result<Placement> {
        if !pixel.is_finite() {
            return Err(Error::invalid(format!(
                "place: pixel ({}, {}) is not finite",
                pixel.x, pixel.y
            )));
        }
        // A click that lands in a crack of the mesh (a cut at a depth discontinuity, a pixel
        // without depth) means the surface next to it: try the nearest pixels within the search
        // radius, nearest first, before giving up.
        let r = PLACE_SEARCH_RADIUS_PX as i32;
        let mut offsets: Vec<(i32, i32)> = (-r..=r)
            .flat_map(|dy| (-r..=r).map(move |dx| (dx, dy)))
            .filter(|(dx, dy)| dx * dx + dy * dy <= r * r)
            .collect();
        offsets.sort_by_key(|(dx, dy)| dx * dx + dy * dy);
        let hit_pixel = offsets
            .iter()
            .map(|&(dx, dy)| pixel + Vec2::new(dx as f32, dy as f32))
            .find(|p| self.bvh.closest_hit(&camera_ray(self.camera, *p)).is_some());
        let Some(hit_pixel) = hit_pixel else {
            return Err(Error::invalid(format!(
                "place: no scene surface at pixel ({}, {}) or within {PLACE_SEARCH_RADIUS_PX} px \
                 of it (no depth there)",
                pixel.x, pixel.y
            )));
        };
        self.place_on_ray(
            &camera_ray(self.camera, hit_pixel),
            size_m,
            yaw_rad,
            options,
        )
    }

    /// [`place_on_ray`], with the depth's confidence (module documentation).
    ///
    /// # Errors
    /// As [`place_on_ray`].
    pub fn place_on_ray(
        &self,
        ray: &Ray,
        size_m: f32,
        yaw_rad: f32,
        options: &PlaceOptions,
    ) -> Result<Placement> {
        let filled =
            FilledDepth::for_camera(self.confidence, self.camera).map(|f| (self.camera, f));
        stand_on_ray(
            self.bvh,
            self.surfaces,
            filled,
            ray,
            size_m,
            yaw_rad,
            options,
        )
    }
}

/// The placement of [`place_on_ray`]; `filled` (with the camera it belongs to) lets a hit where
/// the depth was filled snap by the looser rule of the module documentation.
fn stand_on_ray(
    bvh: &Bvh,
    surfaces: &Surfaces,
    filled: Option<(&Camera, FilledDepth)>,
    ray: &Ray,
    size_m: f32,
    yaw_rad: f32,
    options: &PlaceOptions,
) -> Result<Placement> {
    if !(size_m.is_finite() && size_m > 0.0) {
        return Err(Error::invalid(format!(
            "place: size must be finite and > 0 metres, got {size_m}"
        )));
    }
    if !yaw_rad.is_finite() {
        return Err(Error::invalid(format!(
            "place: yaw {yaw_rad} is not finite"
        )));
    }
    let tilt_ok = (0.0..=90.0).contains(&options.max_tilt_deg);
    let tolerance_ok = |t: f32| t.is_finite() && t >= 0.0;
    if !(tilt_ok
        && tolerance_ok(options.snap_tolerance)
        && tolerance_ok(options.unmeasured_snap_tolerance))
    {
        return Err(Error::invalid(format!(
            "place: max_tilt_deg must be in [0, 90] and snap_tolerance and \
             unmeasured_snap_tolerance finite ≥ 0, got {}, {} and {}",
            options.max_tilt_deg, options.snap_tolerance, options.unmeasured_snap_tolerance
        )));
    }
    let model = model_normalisation(options.model_bounds)?;
    if !(ray.origin.is_finite() && ray.direction.is_finite() && ray.direction.length() > 0.0) {
        return Err(Error::invalid(
            "place: the ray is not finite or has no direction",
        ));
    }
    let hit = bvh
        .closest_hit(ray)
        .ok_or_else(|| Error::invalid("place: the ray hits no surface of the scene"))?;

    let dir = ray.direction.normalize();
    let snapped = snap_measured(surfaces, ray, &hit, options.snap_tolerance).or_else(|| {
        let (camera, filled) = filled?;
        // Only a hit inside the image has a confidence.
        camera.project_to_pixel(hit.point)?;
        let (pixel, _) = camera.project(hit.point)?;
        if !filled.at(pixel) {
            return None;
        }
        snap_unmeasured(
            surfaces,
            ray,
            &hit,
            pixel,
            options.unmeasured_snap_tolerance,
        )
    });
    let (surface, base, normal) = match snapped {
        Some((i, p)) => (Some(i), p, surfaces.surfaces[i].normal),
        None => (None, hit.point, hit.normal),
    };

    let up = match options.orientation {
        Orientation::Gravity => surfaces.up,
        Orientation::SurfaceNormal => normal,
        Orientation::Auto => {
            let tilt = normal.angle_between(surfaces.up).to_degrees();
            let horizontal = tilt <= options.max_tilt_deg;
            let vertical = (tilt - 90.0).abs() <= options.max_tilt_deg;
            // A detected plane's normal is trusted at any slant; one vertex normal only when it
            // is clearly a wall's: stereo vertex normals in between are mostly noise.
            if horizontal || (surface.is_none() && !vertical) {
                surfaces.up
            } else {
                normal
            }
        }
    };
    // Front: towards where the ray came from, flattened onto the plane ⟂ up; looking straight
    // along up, the image's "down" direction instead.
    let flatten = |v: Vec3| (v - up * up.dot(v)).try_normalize();
    let front = flatten(-dir)
        .filter(|_| dir.dot(up).abs() < 0.999)
        .or_else(|| flatten(Vec3::NEG_Y))
        .or_else(|| flatten(Vec3::Z))
        .unwrap_or_else(|| up.any_orthonormal_vector());
    let front = glam::Quat::from_axis_angle(up, yaw_rad) * front;
    let x = up.cross(front).normalize();
    let rotation = Mat3::from_cols(x, up, front);
    let transform = Mat4::from_translation(base)
        * Mat4::from_mat3(rotation)
        * Mat4::from_scale(Vec3::splat(size_m))
        * model;
    if !transform.is_finite() {
        return Err(Error::invalid(format!(
            "place: size {size_m} m at {base} gives a transform that does not fit f32"
        )));
    }
    Ok(Placement {
        transform,
        base,
        up,
        surface_normal: normal,
        surface,
        hit,
    })
}

/// The plane the hit snaps onto by the usual rule, and the point where the ray meets it: the hit
/// lies within `tolerance` × its distance of the plane and either inside its extent or with a
/// normal like the plane's. A plane fitted to thousands of points knows its orientation better
/// than the noisy normal of one stereo vertex, so inside the extent the vertex normal is not
/// asked. Planes whose extent holds the hit go first, the nearest of them: a small piece
/// elsewhere whose plane happens to pass closer (a floor patch fitted to biased stereo depth
/// under a table) is not the surface under the hit.
fn snap_measured(
    surfaces: &Surfaces,
    ray: &Ray,
    hit: &Hit,
    tolerance: f32,
) -> Option<(usize, Vec3)> {
    let distance = (hit.point - ray.origin).length();
    let cos20 = 20f32.to_radians().cos();
    surfaces
        .surfaces
        .iter()
        .enumerate()
        .map(|(i, s)| {
            (
                i,
                s,
                s.contains_point(hit.point),
                s.distance(hit.point).abs(),
            )
        })
        .filter(|&(_, s, inside, off)| {
            off <= tolerance * distance && (inside || s.normal.dot(hit.normal) >= cos20)
        })
        .min_by(|a, b| (!a.2).cmp(&!b.2).then(a.3.total_cmp(&b.3)))
        .and_then(|(i, s, _, _)| Some((i, ray_meets_plane(ray, s)?)))
}

/// The plane a hit on filled depth (seen at image position `pixel`) snaps onto: the largest of the
/// level, vertical or overhead planes whose image extent holds the pixel and whose intersection
/// with the ray lies within `tolerance` × the hit's distance of the hit (module documentation).
fn snap_unmeasured(
    surfaces: &Surfaces,
    ray: &Ray,
    hit: &Hit,
    pixel: Vec2,
    tolerance: f32,
) -> Option<(usize, Vec3)> {
    let distance = (hit.point - ray.origin).length();
    // Surfaces come largest first. The nearest plane to the hit would follow the fill's own
    // error: on `clutter`'s floor under the table it took a slanted plane through the table and
    // the floor. Slanted planes are left out: on noisy stereo they are mostly such planes through
    // several surfaces (`clutter` has one tilted 37° ranked third, `room` one tilted 58° ranked
    // second), and an object stood on one leans with it.
    surfaces
        .surfaces
        .iter()
        .enumerate()
        .filter(|(_, s)| s.kind != SurfaceKind::Slanted && s.contains_pixel(pixel))
        .find_map(|(i, s)| {
            let point = ray_meets_plane(ray, s)?;
            let gap = ((point - ray.origin).length() - distance).abs();
            (gap <= tolerance * distance).then_some((i, point))
        })
}

/// Where the ray meets the surface's plane in front of its origin; `None` for a ray along the
/// plane or pointing away from it.
fn ray_meets_plane(ray: &Ray, surface: &SupportSurface) -> Option<Vec3> {
    let dir = ray.direction.normalize();
    let denom = surface.normal.dot(dir);
    if denom.abs() < 1e-6 {
        return None;
    }
    let t = (surface.offset - surface.normal.dot(ray.origin)) / denom;
    (t > 0.0 && t.is_finite()).then(|| ray.origin + dir * t)
}

/// Moves a model's bottom centre to the origin and scales its largest side to 1.
fn model_normalisation(bounds: Option<[Vec3; 2]>) -> Result<Mat4> {
    let Some([lo, hi]) = bounds else {
        return Ok(Mat4::IDENTITY);
    };
    let size = hi - lo;
    let largest = size.max_element();
    if !(lo.is_finite() && hi.is_finite() && size.min_element() >= 0.0 && largest > 0.0) {
        return Err(Error::invalid(format!(
            "place: model bounds min {lo} max {hi} are not a finite box of positive size"
        )));
    }
    let bottom_centre = Vec3::new((lo.x + hi.x) / 2.0, lo.y, (lo.z + hi.z) / 2.0);
    Ok(Mat4::from_scale(Vec3::splat(1.0 / largest)) * Mat4::from_translation(-bottom_centre))
}

/// The image position a placed object's base projects to (handy for hosts and tests).
pub fn base_pixel(camera: &Camera, placement: &Placement) -> Option<Vec2> {
    camera.project(placement.base).map(|(px, _)| px)
}
