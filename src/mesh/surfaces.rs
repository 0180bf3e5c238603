//! Support surfaces (thesis §6.2): the planes of the scene that objects can rest on or hang from,
//! found by RANSAC on oriented points (points and normals of the scene mesh) with least-squares
//! refinement and a connectivity check in the image; and the gravity "up" estimated from the
//! largest near-horizontal planes.
//!
//! Each round samples planes (through three points whose normals agree with the plane, or through
//! one point along its own normal), scores them by the points within a distance tolerance and a
//! normal tolerance, refits the best one by least squares, keeps only its largest piece that is
//! connected in the image (a table top and a chair seat at the same height are two surfaces), and
//! removes it from the pool. A hypothesis whose largest piece is too small is dropped and the
//! search goes on.
//!
//! ## Extent
//! The refined plane's *members* are the points within the looser membership tolerances
//! ([`SurfaceOptions::membership_tolerance`], [`SurfaceOptions::membership_normal_tolerance_deg`]):
//! on a table top seen at a grazing angle, stereo normals scatter past the inlier angle, and a
//! surface made of its inliers alone covered a third of the `room` table's pixels (rendered at
//! 64 spp; docs/reconstruction-eval.md, stop 28). Its extent is the members' largest connected
//! piece joined with every other piece of at least a quarter of the smallest surface's size that
//! it reaches across at most 12 cells of the connectivity grid (each about 1 % of the larger image
//! side) whose points *hide* the plane (lie on it, or between the camera and the plane along
//! their rays): what stands on a surface splits its visible part, and the surface goes on behind
//! it. A gap through which the camera sees what lies behind the plane (the floor between two
//! tables of the same height) is not crossed, nor is a long way round (a stool top and a box top
//! of equal height across a room).
//!
//! ## Noise model
//! Depth from stereo has constant noise in *inverse* depth `w = 1/Z` (`σ_w = σ_d / (f·B)` for a
//! disparity noise `σ_d`; the familiar `σ_Z ≈ Z²·σ_d/(f·B)`), and on a plane `w` is an affine
//! function of the pixel. So `σ_w` is estimated from the mesh's own samples (robustly, from second
//! differences on its pixel grid), a point is on a plane when its inverse depth is within
//! `3·σ_w` of the plane's along its ray — equivalently, its distance from the plane is within
//! `3·σ_w·Z·|D|` for a plane at distance `D` from the camera — or within the relative
//! [`SurfaceOptions::distance_tolerance`], whichever is larger; and planes are refined by linear
//! least squares of `w` over the pixel coordinates, which weights every point by its true
//! precision (a principal-axis fit in 3D lets the noisiest, farthest points dominate). A plane's
//! members may lie twice as far off it as its inliers (`6·σ_w`); [`Surfaces`] keeps `σ_w`, so
//! that [`Surfaces::snap_mesh_normals`] gives a vertex the plane's normal by the same allowance
//! (its own normal must agree too, so that what stands on a surface keeps its normals, unless
//! the matcher filled most of that surface and its normals tell nothing).
//!
//! ## Measured and filled depth
//! Given the depth's confidence ([`detect_surfaces_with_confidence`]; the scene passes the stereo
//! matcher's, which is 0 on the holes it filled, or the host's), planes are hypothesised, scored
//! and fitted on measured points only, while filled points on a plane still count as its members.
//! On noisy pairs most pixels can be filled ones (85 % on a 16-spp `room` render), and a fill
//! across a hole is an interpolation, not a measurement. The final fit of each surface is
//! reweighted (Tukey's biweight on its inverse-depth residuals, with their own robust scale) so
//! that runs of gross stereo errors inside the wide inlier band do not tilt it.
//!
//! A plane within 10° of up (the estimated one, or the host's given to
//! [`detect_surfaces_with_host_up`]) whose points the levelled plane (normal = up) explains about
//! as well as its own fit is levelled: indoors, support surfaces are level, and a small
//! plane's fitted tilt is mostly stereo error (see `levelled` in the source).
//!
//! ## Level planes first
//! Once the planes of a first search give up (or the host gives it), the search runs again from
//! the full pool, taking level planes (normal = up, through one point) first and planes of any
//! orientation after them: where a narrow table top is seen at a grazing angle with objects on
//! it, a plane tipped through the table and the objects' fronts can hold more points than the
//! table alone, and RANSAC takes the larger. A level band is a surface when its own fit levels,
//! or tilts by at most 4° (the matcher's fronto-parallel bias on such a table: 3° measured), and
//! the surface ends where the band ends (a band across a ramp is a strip of a larger plane,
//! judged among all the points no surface has claimed, including those of bands already found
//! not to be level). Up stays the first search's.
//!
//! "Up" is the inlier-weighted mean normal of the near-horizontal planes (normals within 35° of the
//! camera's +Y, or of −Y for ceilings: the gravity prior of a camera pitched or rolled by less than
//! that) that agree within 10° with the direction most of their points agree with, estimated once
//! more from only those of them that level (a sloped plane says nothing about gravity). Which
//! planes level is judged against the direction that levels the most points: that mean, or one
//! of the planes' own normals. A floor and a 5° ramp beside it lie within 10° of each other, and
//! under little noise neither levels to their mean, which would tilt up by half the ramp's slope;
//! the floor's normal levels the floor and not the ramp. With no near-horizontal plane, up falls
//! back to the camera's +Y (the image's "up", i.e. −image-y).

use glam::{DVec3, Vec2, Vec3};
use rayon::prelude::*;

use super::filled::FilledDepth;
use super::SceneMesh;
use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::image::Raster;
use crate::robust::{tukey, MAD_TO_SIGMA, TUKEY_C};

/// How surfaces are searched for.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SurfaceOptions {
    /// At most this many surfaces, largest first. Default 16 (a cluttered room has a dozen planes
    /// larger than its table top: walls, floor pieces, box sides).
    pub max_surfaces: usize,
    /// A point is on a plane when its distance is below this fraction of its depth (or within the
    /// depth noise measured on the mesh, when that is larger: see the module docs). Default 0.01.
    pub distance_tolerance: f32,
    /// …and its normal within this many degrees of the plane's. Default 15°.
    pub normal_tolerance_deg: f32,
    /// Smallest surface, as a fraction of the points. Default 0.005: a table top seen at a grazing
    /// angle, partly hidden by what stands on it, covers well under 1 % of a room photo.
    pub min_fraction: f32,
    /// RANSAC hypotheses per surface. Default 300.
    pub iterations: usize,
    /// Points used (the mesh's vertices are thinned evenly beyond this). Default 60 000.
    pub max_points: usize,
    /// Seed of the sampler: the result is deterministic for a given seed.
    pub seed: u64,
}

impl Default for SurfaceOptions {
    fn default() -> Self {
        SurfaceOptions {
            max_surfaces: 16,
            distance_tolerance: 0.01,
            normal_tolerance_deg: 15.0,
            min_fraction: 0.005,
            iterations: 300,
            max_points: 60_000,
            seed: 0x5eed,
        }
    }
}

impl SurfaceOptions {
    /// The tolerance (fraction of a point's depth) within which a point counts as lying on a
    /// surface found with these options, for [`Surfaces::surface_at`] and
    /// [`Surfaces::snap_normals`]: twice `distance_tolerance`, the spread of a plane's own inliers.
    pub fn membership_tolerance(&self) -> f32 {
        MEMBERSHIP_FACTOR * self.distance_tolerance
    }

    /// The angle (degrees) within which a mesh normal counts as the normal of a surface found
    /// with these options, for [`Surfaces::snap_mesh_normals`]: twice `normal_tolerance_deg`, as
    /// [`SurfaceOptions::membership_tolerance`] is for distance (the inliers' own normals spread
    /// up to `normal_tolerance_deg`), and below 90° so that a box side standing on a floor does
    /// not take the floor's normal (unless the matcher filled most of the floor: see
    /// [`Surfaces::snap_mesh_normals_with_confidence`]).
    pub fn membership_normal_tolerance_deg(&self) -> f32 {
        (2.0 * self.normal_tolerance_deg).min(MAX_SNAP_ANGLE_DEG)
    }

    /// Checks every field.
    ///
    /// # Errors
    /// `InvalidArgument` naming the bad field.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(Error::invalid(format!("surface options: {m}")));
        if !(self.distance_tolerance.is_finite() && self.distance_tolerance > 0.0) {
            return bad(format!(
                "distance_tolerance must be finite and > 0, got {}",
                self.distance_tolerance
            ));
        }
        if !(self.normal_tolerance_deg > 0.0 && self.normal_tolerance_deg < 90.0) {
            return bad(format!(
                "normal_tolerance_deg must be in (0, 90), got {}",
                self.normal_tolerance_deg
            ));
        }
        if !(self.min_fraction > 0.0 && self.min_fraction <= 1.0) {
            return bad(format!(
                "min_fraction must be in (0, 1], got {}",
                self.min_fraction
            ));
        }
        if self.iterations == 0 || self.max_points < 3 {
            return bad("iterations must be ≥ 1 and max_points ≥ 3".into());
        }
        Ok(())
    }
}

/// Orientation of a surface relative to the estimated up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SurfaceKind {
    /// Faces up within 10° (floor, table top): objects can stand on it.
    Horizontal,
    /// Faces down within 10° (ceiling, underside of a shelf).
    Overhead,
    /// Within 10° of vertical (wall, cupboard front).
    Vertical,
    /// Anything else.
    Slanted,
}

/// Where the up vector came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum UpSource {
    /// From the near-horizontal planes found.
    Planes,
    /// No near-horizontal plane: the camera's +Y.
    CameraFallback,
    /// Given by the host (gravity from an IMU or an AR runtime: [`Surfaces::with_host_up`]).
    Host,
}

/// A planar surface of the scene.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SupportSurface {
    /// Unit normal, on the side facing the camera: the fitted plane's, or ±up exactly for a
    /// near-horizontal plane that fits its points as well levelled (module docs).
    pub normal: Vec3,
    /// Mean of the member points, metres (projected onto the plane).
    pub centroid: Vec3,
    /// Plane offset: points `p` on the plane satisfy `normal · p = offset`.
    pub offset: f32,
    /// Number of mesh vertices on the surface, its members (module docs; before thinning beyond
    /// `max_points`, scaled back).
    pub inliers: usize,
    /// Flatness: root-mean-square distance of the members from the plane, metres.
    pub rms_m: f32,
    /// Area of the extent polygon, m².
    pub area_m2: f32,
    /// Extent: convex hull of the members on the plane, metres, counter-clockwise seen along
    /// −normal.
    pub polygon: Vec<Vec3>,
    /// The same polygon projected into the image, pixels.
    pub polygon_image: Vec<Vec2>,
    /// Orientation relative to [`Surfaces::up`].
    pub kind: SurfaceKind,
}

impl SupportSurface {
    /// Signed distance of `p` from the plane (positive on the camera's side), metres.
    pub fn distance(&self, p: Vec3) -> f32 {
        self.normal.dot(p) - self.offset
    }

    /// Whether the image position lies inside the surface's image polygon.
    pub fn contains_pixel(&self, pixel: Vec2) -> bool {
        point_in_polygon(pixel, &self.polygon_image)
    }

    /// How far the point seen at `pixel` lies off the surface, as a fraction of the distance it
    /// may lie off and still be on it: within `tolerance` × its depth of the plane, or within
    /// `inverse_depth` (1/m) of the plane's inverse depth along its ray, whichever is larger
    /// (module docs, "Noise model"). `None` when the pixel is outside the image polygon or the
    /// point beyond that distance.
    fn offness(&self, pixel: Vec2, point: Vec3, tolerance: f32, inverse_depth: f32) -> Option<f32> {
        let allowed = allowed_off_plane(-point.z, self.offset, tolerance, inverse_depth);
        let distance = self.distance(point).abs();
        // Compared before dividing: a zero allowance holds a point exactly on the plane, and a
        // point behind the camera (negative allowance) nothing.
        (distance <= allowed && self.contains_pixel(pixel)).then(|| {
            if allowed > 0.0 {
                distance / allowed
            } else {
                0.0
            }
        })
    }

    /// Whether the foot of `p` on the plane lies inside the extent polygon.
    pub fn contains_point(&self, p: Vec3) -> bool {
        let u = self.normal.any_orthonormal_vector();
        let v = self.normal.cross(u);
        let on_plane = |q: Vec3| Vec2::new((q - self.centroid).dot(u), (q - self.centroid).dot(v));
        let polygon: Vec<Vec2> = self.polygon.iter().map(|&q| on_plane(q)).collect();
        point_in_polygon(on_plane(p), &polygon)
    }
}

/// The surfaces found, largest first, and the gravity "up".
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Surfaces {
    /// Planes, largest (most inliers) first.
    pub surfaces: Vec<SupportSurface>,
    /// Unit up vector in the camera (= world) frame.
    pub up: Vec3,
    /// Whether `up` came from planes, from the host, or is the camera fallback.
    pub up_source: UpSource,
    /// Noise of the depth the surfaces were found on: the standard deviation `σ_w` of its inverse
    /// depth, 1/m, as detection measured it (module docs, "Noise model"); 0 when unknown. A
    /// vertex within [`MEMBERSHIP_SIGMAS`] `σ_w` of a plane's inverse depth may take its normal
    /// ([`Surfaces::snap_mesh_normals`]), as it counts as the plane's member.
    #[serde(default)]
    pub inverse_depth_noise: f32,
}

impl SurfaceKind {
    /// The kind of a plane with unit `normal` (facing the camera) under gravity `up`: within 10°
    /// of up, of down, or of perpendicular to up, else slanted.
    pub fn relative_to(normal: Vec3, up: Vec3) -> SurfaceKind {
        let c = normal.dot(up);
        let (sin10, cos10) = 10f32.to_radians().sin_cos();
        if c >= cos10 {
            SurfaceKind::Horizontal
        } else if c <= -cos10 {
            SurfaceKind::Overhead
        } else if c.abs() <= sin10 {
            SurfaceKind::Vertical
        } else {
            SurfaceKind::Slanted
        }
    }
}

/// `up` normalised, or `InvalidArgument` when it is not finite or (nearly) zero.
pub(crate) fn validated_up(up: Vec3) -> Result<Vec3> {
    match up.try_normalize() {
        Some(u) if up.is_finite() && up.length() > 1e-6 => Ok(u),
        _ => Err(Error::invalid(format!(
            "up must be a finite non-zero vector, got {up}"
        ))),
    }
}

impl Surfaces {
    /// The same planes under the host's gravity `up` (camera frame; normalised here): an IMU or an
    /// AR runtime knows it far better than the planes of a noisy depth map do. Each surface's kind
    /// is re-derived from it; `up_source` becomes [`UpSource::Host`]. The planes keep their
    /// normals: [`detect_surfaces_with_host_up`] also levels them to the host's up.
    ///
    /// # Errors
    /// `InvalidArgument` when `up` is not finite or has zero length.
    pub fn with_host_up(mut self, up: Vec3) -> Result<Surfaces> {
        let up = validated_up(up)?;
        for s in &mut self.surfaces {
            s.kind = SurfaceKind::relative_to(s.normal, up);
        }
        self.up = up;
        self.up_source = UpSource::Host;
        Ok(self)
    }

    /// The surface that holds the point seen at `pixel` (continuous pixels): the pixel lies inside
    /// the surface's image polygon and the point within `tolerance` × its depth of the plane.
    /// Where several hold it, the one whose plane passes nearest (where two planes cross, a
    /// point near the crossing lies within the tolerance of both).
    ///
    /// The point's normal is not asked, so the allowance does not widen with the depth's noise
    /// as [`Surfaces::snap_mesh_normals`]' does: it would hold the foot of everything standing
    /// on a floor on the floor.
    pub fn surface_at(&self, pixel: Vec2, point: Vec3, tolerance: f32) -> Option<usize> {
        self.nearest_holding(pixel, point, tolerance, 0.0, |_, _| true)
    }

    /// The index of the surface nearest the point, relative to the distance it may lie off
    /// ([`SupportSurface::offness`]), among those that hold it and that `accept`.
    fn nearest_holding(
        &self,
        pixel: Vec2,
        point: Vec3,
        tolerance: f32,
        inverse_depth: f32,
        accept: impl Fn(usize, &SupportSurface) -> bool,
    ) -> Option<usize> {
        self.surfaces
            .iter()
            .enumerate()
            .filter(|&(i, s)| accept(i, s))
            .filter_map(|(i, s)| Some((i, s.offness(pixel, point, tolerance, inverse_depth)?)))
            // Ties go to the first (larger) surface.
            .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
            .map(|(i, _)| i)
    }

    /// Replaces the normal of every pixel whose point lies on a detected surface
    /// ([`Surfaces::surface_at`] with `tolerance`) by that surface's normal, and returns how many
    /// pixels it replaced. A plane fitted to thousands of points knows its orientation far better
    /// than a normal estimated from a stereo pixel's neighbourhood; pixels on no surface keep
    /// theirs. `depth` (metres, NaN = none) and `normals` must have the camera's size; other sizes
    /// leave `normals` unchanged.
    pub fn snap_normals(
        &self,
        depth: &Raster<f32>,
        camera: &Camera,
        normals: &mut Raster<[f32; 3]>,
        tolerance: f32,
    ) -> usize {
        let size = (camera.width as usize, camera.height as usize);
        if self.surfaces.is_empty()
            || (depth.width(), depth.height()) != size
            || (normals.width(), normals.height()) != size
        {
            return 0;
        }
        let mut replaced = 0;
        for y in 0..size.1 {
            for x in 0..size.0 {
                let pixel = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let Some(point) = camera.unproject(pixel.x, pixel.y, *depth.get(x, y)) else {
                    continue;
                };
                if let Some(i) = self.surface_at(pixel, point, tolerance) {
                    *normals.get_mut(x, y) = self.surfaces[i].normal.to_array();
                    replaced += 1;
                }
            }
        }
        replaced
    }

    /// Gives every vertex of `mesh` (a grid mesh of `camera`'s image: its UVs locate each
    /// vertex's pixel) that lies on a detected surface the surface's normal, and returns how many
    /// it changed. A vertex lies on a surface when its pixel is inside the surface's image
    /// polygon, its own normal within `max_angle_deg` of the plane's, and its point within
    /// `distance_tolerance` × its depth of the plane or within [`MEMBERSHIP_SIGMAS`] `σ_w` of
    /// the plane's inverse depth ([`Surfaces::inverse_depth_noise`]), whichever is larger; where
    /// several surfaces qualify, the nearest (relative to that allowance) wins. Tangents are
    /// recomputed around the new normals.
    ///
    /// Why: a plane fitted to thousands of points knows its orientation far better than a local
    /// fit to one vertex's neighbourhood of noisy stereo depth, and a support surface whose
    /// normals scatter by a few degrees shades unevenly under a light. The angle test keeps the
    /// vertices of objects that touch a plane (a box side on the floor, a rounded edge) their own
    /// normals. The distance has to allow for the noise: on a 16-spp `room` render a floor
    /// vertex lies typically more than 2 % of its depth off the floor plane, and the floor's
    /// median normal error was 11.6° with that alone (1.2° with the noise; docs/
    /// reconstruction-eval.md, stop 34).
    ///
    /// [`Surfaces::snap_mesh_normals_with_confidence`] does the same for a mesh whose depth was
    /// partly filled, and uses what the confidence tells.
    pub fn snap_mesh_normals(
        &self,
        mesh: &mut SceneMesh,
        camera: &Camera,
        distance_tolerance: f32,
        max_angle_deg: f32,
    ) -> usize {
        self.snap_mesh_normals_with_confidence(
            mesh,
            camera,
            None,
            distance_tolerance,
            max_angle_deg,
        )
    }

    /// [`Surfaces::snap_mesh_normals`] for a mesh whose depth came with a per-pixel confidence
    /// (the stereo matcher's, 0 on the holes it filled, or a host's; the camera's size, else not
    /// used).
    ///
    /// **Where the matcher filled most of a surface.** The matcher fills what it could not
    /// measure from the measurements around it, and on a noisy photo that can be most of a floor
    /// (60–77 % of the floors' vertices on the 16-spp built-in renders). A normal fitted over
    /// filled depth, or over a neighbourhood that is mostly filled, says nothing about the
    /// surface: there the floors' vertex normals scattered by 41–44° about their mean, the angle
    /// test refused most of them, and the floors' median normal error stayed at 61° and 79°
    /// (`clutter`, `window`; docs/reconstruction-eval.md, stop 48). So:
    /// - a level, vertical or overhead surface on which most vertices (those within its
    ///   allowance, in its polygon) lie on filled depth has the angle test dropped;
    /// - a filled vertex may also lie up to [`UNMEASURED_TOLERANCE`] × its depth off such a
    ///   surface: a fill across a dark stretch of floor can be 15–20 % off (stop 47), far beyond
    ///   a measured point's allowance;
    /// - each vertex takes the nearest surface that holds it.
    ///
    /// Slanted surfaces keep the test: on such depth they are mostly planes through several
    /// surfaces, recognised by their normals alone. Where most of a surface was measured, its
    /// vertices are judged as [`Surfaces::snap_mesh_normals`] judges them.
    pub fn snap_mesh_normals_with_confidence(
        &self,
        mesh: &mut SceneMesh,
        camera: &Camera,
        confidence: Option<&Raster<f32>>,
        distance_tolerance: f32,
        max_angle_deg: f32,
    ) -> usize {
        if self.surfaces.is_empty() || mesh.normals.len() != mesh.positions.len() {
            return 0;
        }
        let inverse_depth = MEMBERSHIP_SIGMAS * self.inverse_depth_noise;
        let size = Vec2::new(camera.width as f32, camera.height as f32);
        let filled_depth = FilledDepth::for_camera(confidence, camera);
        let filled = |pixel: Vec2| filled_depth.is_some_and(|f| f.at(pixel));
        let min_cos = max_angle_deg.to_radians().cos();
        let dropped = match filled_depth {
            Some(_) => self.mostly_filled(mesh, size, distance_tolerance, inverse_depth, filled),
            None => vec![false; self.surfaces.len()],
        };
        let replaced: usize = mesh
            .positions
            .par_iter()
            .zip(mesh.normals.par_iter_mut())
            .zip(mesh.uvs.par_iter())
            .map(|((position, normal), uv)| {
                let point = Vec3::from(*position);
                let pixel = Vec2::from(*uv) * size;
                let own = Vec3::from(*normal);
                let on = filled(pixel)
                    .then(|| {
                        self.nearest_holding(pixel, point, UNMEASURED_TOLERANCE, 0.0, |i, _| {
                            dropped[i]
                        })
                    })
                    .flatten()
                    .or_else(|| {
                        self.nearest_holding(
                            pixel,
                            point,
                            distance_tolerance,
                            inverse_depth,
                            |i, s| dropped[i] || own.dot(s.normal) >= min_cos,
                        )
                    });
                on.map_or(0, |i| {
                    *normal = self.surfaces[i].normal.to_array();
                    1
                })
            })
            .sum();
        if replaced > 0 {
            mesh.recompute_tangents_keeping_normals();
        }
        replaced
    }

    /// Per surface, whether it is level, vertical or overhead and most of the vertices on it
    /// (within the allowance, in its polygon) lie on filled depth (`filled`, by pixel): its
    /// angle test is dropped ([`Surfaces::snap_mesh_normals_with_confidence`]).
    fn mostly_filled(
        &self,
        mesh: &SceneMesh,
        size: Vec2,
        distance_tolerance: f32,
        inverse_depth: f32,
        filled: impl Fn(Vec2) -> bool + Sync,
    ) -> Vec<bool> {
        // Per surface: vertices on it, and how many of them are filled.
        let empty = || vec![(0usize, 0usize); self.surfaces.len()];
        let counts = mesh
            .positions
            .par_iter()
            .zip(mesh.uvs.par_iter())
            .fold(empty, |mut counts, (position, uv)| {
                let point = Vec3::from(*position);
                let pixel = Vec2::from(*uv) * size;
                let is_filled = filled(pixel);
                for (s, (on, filled_on)) in self.surfaces.iter().zip(&mut counts) {
                    if s.kind != SurfaceKind::Slanted
                        && s.offness(pixel, point, distance_tolerance, inverse_depth)
                            .is_some()
                    {
                        *on += 1;
                        *filled_on += usize::from(is_filled);
                    }
                }
                counts
            })
            .reduce(empty, |mut a, b| {
                for (x, y) in a.iter_mut().zip(b) {
                    x.0 += y.0;
                    x.1 += y.1;
                }
                a
            });
        counts
            .into_iter()
            .map(|(on, filled_on)| 2 * filled_on > on)
            .collect()
    }
}

/// How far off a surface's plane, as a fraction of its depth, a mesh vertex on filled depth may
/// lie and still take the plane's normal, on a surface the matcher filled mostly
/// ([`Surfaces::snap_mesh_normals_with_confidence`]). A measured vertex may lie
/// [`SurfaceOptions::membership_tolerance`] off (2 % by default) or within the depth's noise.
pub const UNMEASURED_TOLERANCE: f32 = 0.25;

/// Largest angle (degrees) between a mesh normal and the surface normal it is replaced by.
const MAX_SNAP_ANGLE_DEG: f32 = 60.0;

/// Finds the planar surfaces of a scene mesh (preferably the unsimplified grid, so that inlier
/// counts are proportional to image area) and estimates the up vector.
///
/// A mesh with no triangles gives no surfaces and the fallback up.
///
/// # Errors
/// `InvalidArgument` for bad options or camera.
pub fn detect_surfaces(
    mesh: &SceneMesh,
    camera: &Camera,
    options: &SurfaceOptions,
) -> Result<Surfaces> {
    detect_surfaces_with_confidence(mesh, camera, None, options)
}

/// [`detect_surfaces`] for a mesh whose depth came with a per-pixel confidence (the stereo
/// matcher's, or a host's; same size as the camera's image): points whose pixel has confidence 0
/// — the holes the matcher filled by interpolation — still belong to the surfaces they lie on,
/// but planes are hypothesised, scored and fitted on measured points only (on all points when
/// fewer than three are measured). A fill across a hole carries no measurement, and on noisy
/// input most pixels can be filled ones.
///
/// # Errors
/// As [`detect_surfaces`]; `SizeMismatch` when the confidence map is not the camera's size.
pub fn detect_surfaces_with_confidence(
    mesh: &SceneMesh,
    camera: &Camera,
    confidence: Option<&Raster<f32>>,
    options: &SurfaceOptions,
) -> Result<Surfaces> {
    detect(mesh, camera, confidence, options, None)
}

/// [`detect_surfaces_with_confidence`] under the host's gravity `up` (camera frame; normalised
/// here): near-horizontal planes are levelled to it (where they fit as well levelled: module
/// docs) instead of to the up of the planes, and the result is [`Surfaces::with_host_up`]'s.
///
/// # Errors
/// As [`detect_surfaces_with_confidence`] and [`Surfaces::with_host_up`].
pub fn detect_surfaces_with_host_up(
    mesh: &SceneMesh,
    camera: &Camera,
    confidence: Option<&Raster<f32>>,
    options: &SurfaceOptions,
    up: Vec3,
) -> Result<Surfaces> {
    let up = validated_up(up)?;
    detect(mesh, camera, confidence, options, Some(up))?.with_host_up(up)
}

/// The detection itself; `host_up` (unit) replaces the planes' up as the level.
///
/// Two searches when gravity is known: a first one for planes of any orientation, whose
/// near-horizontal planes give up; then, from the full pool again, level planes first and the
/// rest after them. Why: RANSAC takes the plane with the most inliers, and where a table top is a
/// narrow band at a grazing angle with objects standing on it, a plane tipped towards the camera
/// through the table, the objects' fronts and their tops can hold more points than the table
/// alone (on a 256-spp render of `clutter`, tipped 20°: docs/reconstruction-eval.md, stop 32).
/// Given up, a level plane through the table is a hypothesis of its own, and the surfaces
/// objects rest on are what this search is for.
fn detect(
    mesh: &SceneMesh,
    camera: &Camera,
    confidence: Option<&Raster<f32>>,
    options: &SurfaceOptions,
    host_up: Option<Vec3>,
) -> Result<Surfaces> {
    options.validate()?;
    camera.validate()?;
    if let Some(c) = confidence {
        if (c.width(), c.height()) != (camera.width as usize, camera.height as usize) {
            return Err(Error::SizeMismatch(format!(
                "surface confidence map is {}x{} but the camera is {}x{}",
                c.width(),
                c.height(),
                camera.width,
                camera.height
            )));
        }
    }
    let filled = FilledDepth::for_camera(confidence, camera);
    let measured_at = |px: Vec2| !filled.is_some_and(|f| f.at(px));
    let n_all = mesh.positions.len();
    let stride = n_all.div_ceil(options.max_points).max(1);
    let mut points = Vec::new();
    if mesh.normals.len() == n_all {
        for k in (0..n_all).step_by(stride) {
            let p = Vec3::from(mesh.positions[k]);
            let n = Vec3::from(mesh.normals[k]);
            if let Some((px, depth)) = camera.project(p) {
                if n.is_finite() && (n.length() - 1.0).abs() < 1e-3 {
                    let measured = measured_at(px);
                    points.push(Point {
                        p,
                        n,
                        px,
                        depth,
                        measured,
                    });
                }
            }
        }
    }
    let sigma_w = inverse_depth_noise_of(mesh, camera).map_or(0.0, |sigma| sigma as f32);
    let tolerance = Tolerance {
        relative: options.distance_tolerance,
        inverse_depth: INLIER_SIGMAS * sigma_w,
        cos_normal: options.normal_tolerance_deg.to_radians().cos(),
    };
    let membership = Tolerance {
        relative: options.membership_tolerance(),
        inverse_depth: MEMBERSHIP_SIGMAS * sigma_w,
        cos_normal: options.membership_normal_tolerance_deg().to_radians().cos(),
    };
    let search = Search {
        min_inliers: ((points.len() as f32 * options.min_fraction).ceil() as usize).max(3),
        points: &points,
        camera,
        options,
        tolerance,
        membership,
        grid: ImageGrid::new(camera),
    };

    let (mut found, up, up_source) = match host_up {
        Some(host) => {
            let found = search.level_first(host);
            let (up, source) = estimate_up(&found, &points);
            (found, up, source)
        }
        None => {
            let found = search.any_first();
            match level_up(&found, &points) {
                // Up stays the first search's: the second one picks its points by their
                // agreement with it, so its planes are no independent measure of it.
                (up, UpSource::Planes) => (search.level_first(up), up, UpSource::Planes),
                (up, source) => (found, up, source),
            }
        }
    };
    let level_to = host_up.or((up_source == UpSource::Planes).then_some(up));
    if let Some(level) = level_to {
        for f in found.iter_mut() {
            let on_level = if f.level {
                level_plane(&f.plane, &f.piece, &points, level)
            } else {
                levelled(&f.plane, &f.piece, &points, level)
            };
            if let Some(l) = on_level {
                f.plane = l;
            }
        }
    }
    let mut surfaces: Vec<SupportSurface> = found
        .iter()
        .map(|f| describe(&f.plane, &f.piece, &points, camera, up, stride))
        .collect();
    surfaces.sort_by_key(|s| std::cmp::Reverse(s.inliers));
    Ok(Surfaces {
        surfaces,
        up,
        up_source,
        inverse_depth_noise: sigma_w,
    })
}

/// Up from the near-horizontal planes ([`estimate_up`]), estimated once more from only those of
/// them that level to it: a sloped plane says nothing about gravity.
///
/// Which planes level is decided against the direction to which the most measured points level:
/// the mean ([`estimate_up`]'s first answer) or one of the planes' own normals. Against the mean
/// alone, a floor and a 5° ramp beside it (both within [`estimate_up`]'s 10° of each other) pull
/// it between them, neither levels to it under little noise, and the mean, tilted by half the
/// ramp's slope, would stand; against the floor's normal the floor levels and the ramp does not.
fn level_up(found: &[Found], points: &[Point]) -> (Vec3, UpSource) {
    let (mean, source) = estimate_up(found, points);
    if source != UpSource::Planes {
        return (mean, source);
    }
    let levelling = |up: Vec3| -> (usize, Vec<&Found>) {
        let level: Vec<&Found> = found
            .iter()
            .filter(|f| levelled(&f.plane, &f.piece, points, up).is_some())
            .collect();
        (level.iter().map(|f| f.measured(points)).sum(), level)
    };
    // Candidates: the mean first, then the normal of each plane that could stand for up (within
    // `estimate_up`'s gravity prior and 10° of the mean), on the mean's side (a ceiling's
    // flipped). A candidate replaces the best only when more points level to it, so ties keep
    // the mean.
    let cos_gate = MAX_UP_TILT_DEG.to_radians().cos();
    let oriented = found
        .iter()
        .map(|f| f.plane.normal * f.plane.normal.dot(mean).signum())
        .filter(|n| n.y >= cos_gate && n.angle_between(mean).to_degrees() <= LEVEL_MAX_TILT_DEG);
    let mut best = levelling(mean);
    for candidate in oriented {
        let tried = levelling(candidate);
        if tried.0 > best.0 {
            best = tried;
        }
    }
    match estimate_up(best.1, points) {
        (refined, UpSource::Planes) => (refined, UpSource::Planes),
        _ => (mean, source),
    }
}

/// A search's pool of oriented points and its rules.
struct Search<'a> {
    points: &'a [Point],
    camera: &'a Camera,
    options: &'a SurfaceOptions,
    /// When a point is an inlier of a plane.
    tolerance: Tolerance,
    /// When a point is a member of a surface (its extent).
    membership: Tolerance,
    /// Smallest surface, points.
    min_inliers: usize,
    grid: ImageGrid,
}

/// A surface found.
struct Found {
    /// As fitted, not levelled.
    plane: Plane,
    /// Its points.
    piece: Vec<usize>,
    /// Found by the search for level planes: level, whatever its fitted tilt ([`Search::level_planes`]).
    level: bool,
}

impl Found {
    /// How many of its points are measured (not filled): what a plane's say on up weighs, since
    /// filled depth says nothing about a plane's tilt.
    fn measured(&self, points: &[Point]) -> usize {
        self.piece.iter().filter(|&&i| points[i].measured).count()
    }
}

impl Search<'_> {
    /// Planes of any orientation from the whole pool, largest first.
    fn any_first(&self) -> Vec<Found> {
        let mut rng = XorShift(self.options.seed | 1);
        let mut remaining: Vec<usize> = (0..self.points.len()).collect();
        let mut found = Vec::new();
        self.any_planes(&mut remaining, &mut found, &mut rng);
        found
    }

    /// Level planes (normal `up`) from the whole pool, then planes of any orientation from what
    /// they leave.
    fn level_first(&self, up: Vec3) -> Vec<Found> {
        let mut rng = XorShift(self.options.seed | 1);
        let mut remaining: Vec<usize> = (0..self.points.len()).collect();
        let mut found = Vec::new();
        self.level_planes(up, &mut remaining, &mut found, &mut rng);
        self.any_planes(&mut remaining, &mut found, &mut rng);
        found
    }

    /// RANSAC for planes of any orientation in `remaining`, appended to `found` (up to
    /// `max_surfaces` in all); their points leave the pool.
    fn any_planes(&self, remaining: &mut Vec<usize>, found: &mut Vec<Found>, rng: &mut XorShift) {
        let points = self.points;
        // Hypotheses whose best piece was too small are dropped from the pool (so the next round
        // looks elsewhere); after MAX_MISSES in a row the pool holds no more surfaces.
        let mut misses = 0;
        while found.len() < self.options.max_surfaces
            && remaining.len() >= self.min_inliers
            && misses < MAX_MISSES
        {
            let Some(mut plane) =
                best_hypothesis(points, remaining, None, self.options, &self.tolerance, rng)
            else {
                break;
            };
            let mut inliers = Vec::new();
            for _ in 0..3 {
                inliers = self.inliers(remaining, &plane);
                match fit_plane(points, &measured_or_all(points, &inliers), self.camera) {
                    Some(p) => plane = p,
                    None => break,
                }
            }
            let piece = self.grid.largest_component(points, &inliers);
            if piece.len() < self.min_inliers {
                // Too small to be a surface: take its points out of the pool so that the next
                // hypothesis is another one.
                misses += 1;
                drop_from(remaining, &inliers, points.len());
                continue;
            }
            misses = 0;
            if let Some(p) = fit_plane_robust(points, &measured_or_all(points, &piece), self.camera)
            {
                plane = p;
            }
            let piece = self.claim(remaining, &plane, piece);
            found.push(Found {
                plane,
                piece,
                level: false,
            });
        }
    }

    /// RANSAC for level planes (normal `up`, through a point of the pool): each round takes the
    /// level plane with the most inliers, moves it to their median height, and keeps its largest
    /// connected piece when [`Search::as_level`] takes it for a level surface (a band across a
    /// ramp, a dome or the rim of a bowl is not). Appended to `found`; their points leave
    /// `remaining`.
    fn level_planes(
        &self,
        up: Vec3,
        remaining: &mut Vec<usize>,
        found: &mut Vec<Found>,
        rng: &mut XorShift,
    ) {
        let points = self.points;
        // Where level planes are still looked for: what failed as one stays in `remaining` for
        // the search for planes of any orientation.
        let mut pool = remaining.clone();
        let mut misses = 0;
        while found.len() < self.options.max_surfaces
            && pool.len() >= self.min_inliers
            && misses < MAX_MISSES
        {
            let Some(mut plane) =
                best_hypothesis(points, &pool, Some(up), self.options, &self.tolerance, rng)
            else {
                break;
            };
            let mut inliers = Vec::new();
            for _ in 0..3 {
                inliers = self.inliers(&pool, &plane);
                match level_plane(&plane, &inliers, points, up) {
                    Some(p) => plane = p,
                    None => break,
                }
            }
            let piece = self.grid.largest_component(points, &inliers);
            let fitted = (piece.len() >= self.min_inliers)
                .then(|| fit_plane_robust(points, &measured_or_all(points, &piece), self.camera))
                .flatten();
            let Some((fitted, level)) =
                fitted.and_then(|f| Some((f, self.as_level(remaining, &f, &piece, up)?)))
            else {
                misses += 1;
                drop_from(&mut pool, &inliers, points.len());
                continue;
            };
            misses = 0;
            let piece = self.claim(remaining, &level, piece);
            drop_from(&mut pool, &piece, points.len());
            found.push(Found {
                plane: fitted,
                piece,
                level: true,
            });
        }
    }

    /// The level plane of a level hypothesis' `piece` whose free fit is `fitted`, when the piece
    /// is a level surface: `fitted` levels ([`levelled`]) or is tilted from `up` by at most
    /// [`LEVEL_BIAS_TILT_DEG`], and the surface ends where the level band ends — `fitted`'s own
    /// connected inliers among the `unclaimed` points are at most [`LEVEL_BAND_RATIO`] × as many
    /// as the piece (a band across a ramp is a strip of the ramp's plane).
    ///
    /// Why the unclaimed points and not the level search's pool: the pool loses the points of
    /// every band found not to be level, so on a ramp the bands rejected first eat it away, and a
    /// later band across what is left looks like a surface that ends (a 3.5° ramp came out as a
    /// sloped part and a level one).
    ///
    /// Why the tilt rule: the matcher's depth of a narrow table top seen at a grazing angle is
    /// tilted by its fronto-parallel bias (3° on a 256-spp render of `clutter`,
    /// docs/reconstruction-eval.md, stop 32), and because that error is systematic, the levelled
    /// plane fits it clearly worse than its own fit, as it would a real slope.
    fn as_level(
        &self,
        unclaimed: &[usize],
        fitted: &Plane,
        piece: &[usize],
        up: Vec3,
    ) -> Option<Plane> {
        let points = self.points;
        let level = match levelled(fitted, piece, points, up) {
            Some(level) => level,
            None if fitted.normal.dot(up).abs() >= LEVEL_BIAS_TILT_DEG.to_radians().cos() => {
                level_plane(fitted, piece, points, up)?
            }
            None => return None,
        };
        let along = self
            .grid
            .largest_component(points, &self.inliers(unclaimed, fitted));
        (along.len() as f32 <= LEVEL_BAND_RATIO * piece.len() as f32).then_some(level)
    }

    /// The points of `pool` that are inliers of `plane`.
    fn inliers(&self, pool: &[usize], plane: &Plane) -> Vec<usize> {
        pool.iter()
            .copied()
            .filter(|&i| plane.accepts(&self.points[i], &self.tolerance))
            .collect()
    }

    /// The surface of `plane` whose inliers' largest connected piece is `piece`: its extent,
    /// which leaves `remaining`.
    fn claim(&self, remaining: &mut Vec<usize>, plane: &Plane, piece: Vec<usize>) -> Vec<usize> {
        let points = self.points;
        // The surface's extent: its members (looser than its inliers: noisy normals on a grazing
        // table top scatter past the inlier angle) across the pieces that what stands on it
        // splits it into.
        let members: Vec<usize> = remaining
            .iter()
            .copied()
            .filter(|&i| plane.accepts(&points[i], &self.membership))
            .collect();
        // Pieces of a quarter of the smallest surface's size join: smaller ones are as likely
        // to be stereo errors that happen to lie on the plane.
        let extent = self.grid.extent(
            points,
            &members,
            plane,
            &self.membership,
            (self.min_inliers / 4).max(3),
        );
        // Never smaller than the inlier piece (the robust refit may move the plane off some of
        // its points).
        let piece = if extent.len() >= piece.len() {
            extent
        } else {
            piece
        };
        drop_from(remaining, &piece, points.len());
        piece
    }
}

/// Removes `gone` from `pool` (indices below `n`).
fn drop_from(pool: &mut Vec<usize>, gone: &[usize], n: usize) {
    let mut on = vec![false; n];
    for &i in gone {
        on[i] = true;
    }
    pool.retain(|&i| !on[i]);
}

#[derive(Clone, Copy)]
struct Point {
    p: Vec3,
    n: Vec3,
    px: Vec2,
    depth: f32,
    /// Whether its depth was measured (confidence above 0), not filled in.
    measured: bool,
}

/// `normal · p = offset`, normal facing the camera.
#[derive(Clone, Copy, Debug)]
struct Plane {
    normal: Vec3,
    offset: f32,
}

impl Plane {
    fn through(a: Vec3, b: Vec3, c: Vec3) -> Option<Plane> {
        let n = (b - a).cross(c - a).try_normalize()?;
        Some(Plane::facing_camera(n, n.dot(a)))
    }

    fn facing_camera(normal: Vec3, offset: f32) -> Plane {
        // The camera (origin) is on the positive side: normal · 0 − offset > 0.
        if offset > 0.0 {
            Plane {
                normal: -normal,
                offset: -offset,
            }
        } else {
            Plane { normal, offset }
        }
    }

    /// The point's inverse depth minus the plane's along the point's ray, 1/m.
    fn inverse_depth_residual(&self, q: &Point) -> f64 {
        // The ray through the point at unit depth (z = −1) meets the plane at depth offset / n·r.
        let r = q.p.as_dvec3() / q.depth as f64;
        1.0 / q.depth as f64 - self.normal.as_dvec3().dot(r) / self.offset as f64
    }

    fn accepts(&self, q: &Point, tolerance: &Tolerance) -> bool {
        self.on_plane(q, tolerance) && self.normal.dot(q.n).abs() >= tolerance.cos_normal
    }

    /// Whether the point lies within the tolerance's distance of the plane (normal not asked).
    fn on_plane(&self, q: &Point, tolerance: &Tolerance) -> bool {
        let distance = (self.normal.dot(q.p) - self.offset).abs();
        distance
            <= allowed_off_plane(
                q.depth,
                self.offset,
                tolerance.relative,
                tolerance.inverse_depth,
            )
    }

    /// Whether the point hides the plane: it lies between the camera and where its ray meets the
    /// plane (so the plane may continue behind it), or on the plane.
    fn hidden_by(&self, q: &Point, tolerance: &Tolerance) -> bool {
        // The camera is on the positive side; the ray meets the plane only when n · p < 0.
        let along = self.normal.dot(q.p);
        self.on_plane(q, tolerance) || (along < 0.0 && along > self.offset)
    }
}

/// How far (metres) a point at `depth` may lie off a plane at distance `offset` from the camera
/// and still be on it: `relative` × its depth, or `inverse_depth` (1/m) of the plane's inverse
/// depth along its ray, whichever is larger (module docs, "Noise model"). `ScoreSample` repeats
/// this arithmetic in its vectorised loop.
#[inline(always)]
fn allowed_off_plane(depth: f32, offset: f32, relative: f32, inverse_depth: f32) -> f32 {
    // |Δw| = |distance| / (Z·|D|) along the point's ray.
    depth * relative.max(inverse_depth * offset.abs())
}

/// Spacing (in grid steps) of the second differences the plane tolerance's noise is measured
/// with: stereo errors are correlated over several pixels, and a point's offset from a plane
/// includes the slow part that short differences cancel.
const SURFACE_NOISE_SPACING: usize = 8;

/// Consecutive hypotheses whose largest connected piece is too small after which the search
/// ends (each drops its inliers from the pool, so the next one looks elsewhere).
const MAX_MISSES: usize = 24;

/// How many standard deviations of inverse-depth noise a point may lie off its plane.
const INLIER_SIGMAS: f32 = 3.0;

/// A surface's members may lie this many times farther off its plane than its inliers (as
/// [`SurfaceOptions::membership_tolerance`] is to `distance_tolerance`).
const MEMBERSHIP_FACTOR: f32 = 2.0;

/// How many standard deviations of inverse-depth noise a surface's members may lie off its
/// plane ([`Surfaces::inverse_depth_noise`]).
pub const MEMBERSHIP_SIGMAS: f32 = MEMBERSHIP_FACTOR * INLIER_SIGMAS;

/// The widest gap (cells of [`ImageGrid`], each about 1 % of the larger image side) between two
/// pieces of one surface: an object standing on the surface hides a stretch of it about as wide
/// as the object, while a path along a wall to another piece that happens to lie on the same
/// plane (a stool top and a box top of equal height) is long.
const MAX_BRIDGE_CELLS: i32 = 12;

/// A cell joins pieces of a surface when at least this fraction of its points hide the plane
/// (lie on it or in front of it): a little stereo noise behind the plane does not cut the
/// bridge, a view through to what lies behind the plane does.
const BRIDGE_FRACTION: f32 = 0.75;

/// When a point lies on a plane.
struct Tolerance {
    /// Distance as a fraction of the point's depth.
    relative: f32,
    /// Inverse-depth residual, 1/m (`INLIER_SIGMAS · σ_w`; 0 when the noise is unknown).
    inverse_depth: f32,
    /// Cosine of the largest angle between the point's normal and the plane's.
    cos_normal: f32,
}

/// `σ_w` of the mesh's samples (1/m), when its vertices lie on a pixel grid (as the meshes of
/// [`SceneMesh::from_depth`] do): its inverse depths are put back on their pixels and
/// [`super::local_fit::inverse_depth_noise`] measures them at the grid's step.
fn inverse_depth_noise_of(mesh: &SceneMesh, camera: &Camera) -> Option<f64> {
    let (w, h) = (camera.width as usize, camera.height as usize);
    if mesh.uvs.len() != mesh.positions.len() || w < 3 || h < 3 {
        return None;
    }
    let mut raster = crate::image::Raster::filled(w, h, f64::NAN);
    let mut previous: Option<(usize, usize)> = None;
    let mut gaps = Vec::new();
    for (uv, p) in mesh.uvs.iter().zip(&mesh.positions) {
        let x = (uv[0] * w as f32 - 0.5).round();
        let y = (uv[1] * h as f32 - 0.5).round();
        let inside = x >= 0.0 && y >= 0.0 && x < w as f32 && y < h as f32;
        // NaN-safe: only points in front of the camera count.
        if !inside || p[2].is_nan() || p[2] >= 0.0 {
            previous = None;
            continue;
        }
        let (x, y) = (x as usize, y as usize);
        *raster.get_mut(x, y) = -1.0 / p[2] as f64;
        if let Some((px, py)) = previous {
            if py == y && x > px {
                gaps.push(x - px);
            }
        }
        previous = Some((x, y));
    }
    if gaps.is_empty() {
        return None;
    }
    let k = gaps.len() / 2;
    let step = *gaps.select_nth_unstable(k).1;
    super::local_fit::inverse_depth_noise(&raster, SURFACE_NOISE_SPACING * step)
}

/// The measured points among `idx`, or all of `idx` when fewer than three are measured.
fn measured_or_all(points: &[Point], idx: &[usize]) -> Vec<usize> {
    let measured: Vec<usize> = idx
        .iter()
        .copied()
        .filter(|&i| points[i].measured)
        .collect();
    if measured.len() >= 3 {
        measured
    } else {
        idx.to_vec()
    }
}

/// The plane among `options.iterations` random hypotheses that most points of `remaining` (a
/// sample of them on large pools) are inliers of: planes of any orientation, or with `level`,
/// planes of that normal through one point whose own normal agrees with it.
fn best_hypothesis(
    points: &[Point],
    remaining: &[usize],
    level: Option<Vec3>,
    options: &SurfaceOptions,
    tolerance: &Tolerance,
    rng: &mut XorShift,
) -> Option<Plane> {
    const SCORE_SAMPLES: usize = 3000;
    let remaining = &measured_or_all(points, remaining);
    let sample = if remaining.len() <= SCORE_SAMPLES {
        ScoreSample::new(points, remaining.iter().copied())
    } else {
        let picks: Vec<usize> = (0..SCORE_SAMPLES)
            .map(|_| remaining[rng.below(remaining.len())])
            .collect();
        ScoreSample::new(points, picks)
    };
    let mut best: Option<(usize, Plane)> = None;
    for round in 0..options.iterations {
        // Alternate three-point planes (need no normals) and one point along its own normal
        // (robust normals make these the likelier hits on a noisy surface).
        let plane = if let Some(up) = level {
            let a = points[remaining[rng.below(remaining.len())]];
            if up.dot(a.n).abs() < tolerance.cos_normal {
                continue;
            }
            Plane::facing_camera(up, up.dot(a.p))
        } else if round % 2 == 0 {
            let [a, b, c] = [0; 3].map(|_| points[remaining[rng.below(remaining.len())]]);
            let Some(plane) = Plane::through(a.p, b.p, c.p) else {
                continue;
            };
            if [a, b, c]
                .iter()
                .any(|q| plane.normal.dot(q.n).abs() < tolerance.cos_normal)
            {
                continue;
            }
            plane
        } else {
            let a = points[remaining[rng.below(remaining.len())]];
            Plane::facing_camera(a.n, a.n.dot(a.p))
        };
        let score = count_accepted(&sample, &plane, tolerance);
        if best.is_none_or(|(s, _)| score > s) {
            best = Some((score, plane));
        }
    }
    best.map(|(_, p)| p)
}

/// The points RANSAC scores its hypotheses on, as columns: one hypothesis' score is then a
/// plain loop over arrays that the compiler vectorises ([`count_accepted`]), where gathering the
/// sampled points from the whole pool was not (scoring was most of the detection's time).
struct ScoreSample {
    p: [Vec<f32>; 3],
    n: [Vec<f32>; 3],
    depth: Vec<f32>,
}

impl ScoreSample {
    fn new(points: &[Point], idx: impl IntoIterator<Item = usize>) -> ScoreSample {
        let mut sample = ScoreSample {
            p: Default::default(),
            n: Default::default(),
            depth: Vec::new(),
        };
        for i in idx {
            let q = &points[i];
            for axis in 0..3 {
                sample.p[axis].push(q.p[axis]);
                sample.n[axis].push(q.n[axis]);
            }
            sample.depth.push(q.depth);
        }
        sample
    }

    /// How many of the points `plane` accepts: [`Plane::accepts`], with the same arithmetic in
    /// the same order, so the count is the same to the point.
    #[inline(always)]
    fn count_accepted_body(&self, plane: &Plane, tolerance: &Tolerance) -> usize {
        let Plane { normal: m, offset } = *plane;
        let relative = tolerance
            .relative
            .max(tolerance.inverse_depth * offset.abs());
        let [px, py, pz] = &self.p;
        let [nx, ny, nz] = &self.n;
        let len = self.depth.len();
        let (px, py, pz) = (&px[..len], &py[..len], &pz[..len]);
        let (nx, ny, nz) = (&nx[..len], &ny[..len], &nz[..len]);
        let mut count = 0u32;
        for i in 0..len {
            let distance = ((m.x * px[i]) + (m.y * py[i]) + (m.z * pz[i]) - offset).abs();
            let facing = ((m.x * nx[i]) + (m.y * ny[i]) + (m.z * nz[i])).abs();
            let on = distance <= self.depth[i] * relative;
            count += (on & (facing >= tolerance.cos_normal)) as u32;
        }
        count as usize
    }
}

crate::avx2_variant!(fn count_accepted<'a>(sample: &'a ScoreSample, plane: &'a Plane, tolerance: &'a Tolerance) -> usize => ScoreSample::count_accepted_body);

/// Least-squares plane in inverse depth (module docs): `w = α·u + β·v + γ` over the points'
/// pixels, solved about their mean pixel for conditioning. `None` for < 3 points or pixels on a
/// line.
fn fit_plane(points: &[Point], idx: &[usize], camera: &Camera) -> Option<Plane> {
    fit_plane_weighted(points, idx, camera, |_| 1.0)
}

/// Reweighting rounds of [`fit_plane_robust`].
const ROBUST_FIT_ROUNDS: usize = 4;

/// [`fit_plane`], then reweighted by Tukey's biweight on the inverse-depth residuals with their
/// own robust scale: a surface's inliers are gathered with a wide tolerance (its noise measured
/// over long spacings, which stereo's gross errors inflate), and a plain fit lets runs of such
/// errors tilt the plane.
fn fit_plane_robust(points: &[Point], idx: &[usize], camera: &Camera) -> Option<Plane> {
    let mut plane = fit_plane(points, idx, camera)?;
    let mut residuals = vec![0.0f64; idx.len()];
    for _ in 0..ROBUST_FIT_ROUNDS {
        for (r, &i) in residuals.iter_mut().zip(idx) {
            *r = plane.inverse_depth_residual(&points[i]).abs();
        }
        let mut sorted = residuals.clone();
        let k = sorted.len() / 2;
        let scale = MAD_TO_SIGMA * *sorted.select_nth_unstable_by(k, f64::total_cmp).1;
        if !(scale.is_finite() && scale > 0.0) {
            break;
        }
        let c = TUKEY_C * scale;
        let weights: Vec<f64> = residuals.iter().map(|&r| tukey(r, c)).collect();
        match fit_plane_weighted(points, idx, camera, |k| weights[k]) {
            Some(p) => plane = p,
            None => break,
        }
    }
    Some(plane)
}

/// Weighted least-squares plane in inverse depth (see [`fit_plane`]); `weight(k)` of the point
/// `idx[k]`.
fn fit_plane_weighted(
    points: &[Point],
    idx: &[usize],
    camera: &Camera,
    weight: impl Fn(usize) -> f64,
) -> Option<Plane> {
    if idx.len() < 3 {
        return None;
    }
    let total: f64 = (0..idx.len()).map(&weight).sum();
    if !(total.is_finite() && total > 0.0) {
        return None;
    }
    let mean = idx
        .iter()
        .enumerate()
        .map(|(k, &i)| points[i].px.as_dvec2() * weight(k))
        .sum::<glam::DVec2>()
        / total;
    let mut m = [[0.0f64; 3]; 3];
    let mut rhs = [0.0f64; 3];
    for (j, &i) in idx.iter().enumerate() {
        let k = weight(j);
        if k <= 0.0 {
            continue;
        }
        let q = &points[i];
        let d = q.px.as_dvec2() - mean;
        let x = [d.x, d.y, 1.0];
        let w = 1.0 / q.depth as f64;
        for r in 0..3 {
            for c in 0..3 {
                m[r][c] += k * x[r] * x[c];
            }
            rhs[r] += k * x[r] * w;
        }
    }
    let m = glam::DMat3::from_cols_array_2d(&m);
    let det = m.determinant();
    let scale = m.x_axis.x * m.y_axis.y * m.z_axis.z;
    if !(det.is_finite() && scale > 0.0 && det > 1e-9 * scale) {
        return None;
    }
    let theta = m.inverse() * DVec3::from(rhs);
    let (alpha, beta, centre) = (theta.x, theta.y, theta.z);
    let (fx, fy) = (camera.fx as f64, camera.fy as f64);
    let (cx, cy) = (camera.cx as f64, camera.cy as f64);
    // n' · p = −1 with n' = (−α·fx, β·fy, γ + α·cx + β·cy), γ = centre − α·ū − β·v̄.
    let n = DVec3::new(
        -alpha * fx,
        beta * fy,
        centre + alpha * (cx - mean.x) + beta * (cy - mean.y),
    );
    let len = n.length();
    if !(len.is_finite() && len > 0.0) {
        return None;
    }
    let normal = (n / len).as_vec3();
    let offset = (-1.0 / len) as f32;
    (normal.is_finite() && offset.is_finite()).then(|| Plane::facing_camera(normal, offset))
}

/// Occupancy grid over the image for connectivity: cells about 1/100 of the larger image side.
struct ImageGrid {
    cell: f32,
    cols: usize,
    rows: usize,
}

impl ImageGrid {
    fn new(camera: &Camera) -> ImageGrid {
        let cell = (camera.width.max(camera.height) as f32 / 100.0).max(1.0);
        ImageGrid {
            cell,
            cols: (camera.width as f32 / cell).ceil() as usize + 1,
            rows: (camera.height as f32 / cell).ceil() as usize + 1,
        }
    }

    fn cell_of(&self, px: Vec2) -> usize {
        let c = ((px.x / self.cell).max(0.0) as usize).min(self.cols - 1);
        let r = ((px.y / self.cell).max(0.0) as usize).min(self.rows - 1);
        r * self.cols + c
    }

    /// A surface's extent: the members in the largest 8-connected group of cells holding
    /// members, joined with every other group of at least `min_size` members that it reaches
    /// through cells whose points hide the plane ([`Plane::hidden_by`], at least
    /// [`BRIDGE_FRACTION`] of them). Why: a vase on a table, or a sofa on a floor, splits the
    /// surface's visible part into pieces that are one surface continuing behind it, while a gap
    /// through which the camera sees *behind* the plane (the floor between two tables of equal
    /// height) keeps them apart.
    fn extent(
        &self,
        points: &[Point],
        members: &[usize],
        plane: &Plane,
        tolerance: &Tolerance,
        min_size: usize,
    ) -> Vec<usize> {
        let Some(Occupancy {
            count,
            label,
            sizes,
            largest: best,
        }) = self.occupancy(points, members)
        else {
            return Vec::new();
        };
        let cells = count.len();
        let mut seen = vec![0u32; cells];
        let mut hiding = vec![0u32; cells];
        for q in points {
            let c = self.cell_of(q.px);
            seen[c] += 1;
            hiding[c] += plane.hidden_by(q, tolerance) as u32;
        }
        let passable = |c: usize| {
            count[c] > 0 || (seen[c] > 0 && hiding[c] as f32 >= BRIDGE_FRACTION * seen[c] as f32)
        };
        // A piece large enough to join, once reached, is a new starting point.
        let joins = |c: usize| count[c] > 0 && sizes[label[c] as usize] >= min_size as u64;
        let mut keep = vec![false; sizes.len()];
        keep[best] = true;
        // The most gap cells a path may still cross after reaching each cell (−1: unreached).
        let mut budget = vec![-1i32; cells];
        let mut stack: Vec<usize> = (0..cells).filter(|&c| label[c] == best as u32).collect();
        for &c in &stack {
            budget[c] = MAX_BRIDGE_CELLS;
        }
        while let Some(k) = stack.pop() {
            for kk in self.neighbours(k) {
                if !passable(kk) {
                    continue;
                }
                let left = if joins(kk) {
                    MAX_BRIDGE_CELLS
                } else {
                    budget[k] - 1
                };
                if left > budget[kk] {
                    budget[kk] = left;
                    if joins(kk) {
                        keep[label[kk] as usize] = true;
                    }
                    if left > 0 {
                        stack.push(kk);
                    }
                }
            }
        }
        members
            .iter()
            .copied()
            .filter(|&i| {
                let c = self.cell_of(points[i].px);
                budget[c] >= 0 && keep[label[c] as usize]
            })
            .collect()
    }

    /// The 8 neighbours of cell `k` inside the grid.
    fn neighbours(&self, k: usize) -> impl Iterator<Item = usize> + '_ {
        let (r, c) = ((k / self.cols) as i64, (k % self.cols) as i64);
        (-1..=1)
            .flat_map(move |dr| (-1..=1).map(move |dc| (r + dr, c + dc)))
            .filter(move |&(rr, cc)| {
                (rr, cc) != (r, c)
                    && rr >= 0
                    && cc >= 0
                    && rr < self.rows as i64
                    && cc < self.cols as i64
            })
            .map(move |(rr, cc)| rr as usize * self.cols + cc as usize)
    }

    /// Labels the 8-connected groups of cells with a non-zero count: each cell's group
    /// (`u32::MAX` for empty cells) and each group's total count.
    fn label_components(&self, count: &[u32]) -> (Vec<u32>, Vec<u64>) {
        let mut label = vec![u32::MAX; count.len()];
        let mut sizes = Vec::new();
        let mut stack = Vec::new();
        for start in 0..count.len() {
            if count[start] == 0 || label[start] != u32::MAX {
                continue;
            }
            let id = sizes.len() as u32;
            let mut size = 0u64;
            label[start] = id;
            stack.push(start);
            while let Some(k) = stack.pop() {
                size += count[k] as u64;
                for kk in self.neighbours(k) {
                    if count[kk] > 0 && label[kk] == u32::MAX {
                        label[kk] = id;
                        stack.push(kk);
                    }
                }
            }
            sizes.push(size);
        }
        (label, sizes)
    }

    /// The inliers in the largest 8-connected group of occupied cells (by inlier count).
    fn largest_component(&self, points: &[Point], inliers: &[usize]) -> Vec<usize> {
        let Some(occupancy) = self.occupancy(points, inliers) else {
            return Vec::new();
        };
        inliers
            .iter()
            .copied()
            .filter(|&i| occupancy.label[self.cell_of(points[i].px)] == occupancy.largest as u32)
            .collect()
    }

    /// The cells holding the points `idx`: how many each, their 8-connected groups and the
    /// largest group (by point count); `None` when `idx` is empty.
    fn occupancy(&self, points: &[Point], idx: &[usize]) -> Option<Occupancy> {
        let mut count = vec![0u32; self.cols * self.rows];
        for &i in idx {
            count[self.cell_of(points[i].px)] += 1;
        }
        let (label, sizes) = self.label_components(&count);
        let largest = (0..sizes.len()).max_by_key(|&k| sizes[k])?;
        Some(Occupancy {
            count,
            label,
            sizes,
            largest,
        })
    }
}

/// Points per cell of an [`ImageGrid`], grouped ([`ImageGrid::occupancy`]).
struct Occupancy {
    /// Points in each cell.
    count: Vec<u32>,
    /// Each cell's group (`u32::MAX` for empty cells).
    label: Vec<u32>,
    /// Each group's point count.
    sizes: Vec<u64>,
    /// The group with the most points.
    largest: usize,
}

/// Largest angle between a plane's (or a ceiling's flipped) normal and the camera's +Y for it to
/// count towards "up": the gravity prior, i.e. the camera pitched or rolled by at most this much.
const MAX_UP_TILT_DEG: f32 = 35.0;

fn estimate_up<'a>(
    found: impl IntoIterator<Item = &'a Found>,
    points: &[Point],
) -> (Vec3, UpSource) {
    let cos_gate = MAX_UP_TILT_DEG.to_radians().cos();
    // Candidate up directions: normals of near-horizontal planes, ceilings flipped.
    let candidates: Vec<(Vec3, usize)> = found
        .into_iter()
        .filter_map(|f| {
            let n = f.plane.normal;
            let weight = f.measured(points);
            if n.y >= cos_gate {
                Some((n, weight))
            } else if -n.y >= cos_gate {
                Some((-n, weight))
            } else {
                None
            }
        })
        .collect();
    let cos10 = 10f32.to_radians().cos();
    // The reference is the direction most of the horizontal area agrees with (floor and table
    // tops together outvote one large spurious plane).
    let agreeing = |r: Vec3| {
        candidates
            .iter()
            .filter(|(n, _)| n.dot(r) >= cos10)
            .map(|(_, w)| *w)
            .sum::<usize>()
    };
    let Some(&(reference, _)) = candidates.iter().max_by_key(|(n, w)| (agreeing(*n), *w)) else {
        return (Vec3::Y, UpSource::CameraFallback);
    };
    let sum: Vec3 = candidates
        .iter()
        .filter(|(n, _)| n.dot(reference) >= cos10)
        .map(|(n, w)| *n * *w as f32)
        .sum();
    match sum.try_normalize() {
        Some(up) => (up, UpSource::Planes),
        None => (Vec3::Y, UpSource::CameraFallback),
    }
}

/// The plane levelled to gravity: normal ±`up`, through the median height of its measured points,
/// when its fitted normal is within [`LEVEL_MAX_TILT_DEG`] of `up` and the levelled plane explains
/// those points about as well (median inverse-depth residual at most [`LEVEL_RESIDUAL_RATIO`] ×
/// the fitted plane's); `None` otherwise.
///
/// Why: indoors, what objects rest on is level, and a small plane's fitted tilt is mostly the
/// stereo error's (a table top seen at a grazing angle pins its slope along the view poorly: on a
/// 1024-spp render of `clutter` our depth tilts it 5°), while the up vector is fitted to every
/// horizontal plane at once. A surface that really slopes (a ramp, a drawing board) fits its
/// points clearly worse levelled and keeps its own normal.
fn levelled(plane: &Plane, piece: &[usize], points: &[Point], up: Vec3) -> Option<Plane> {
    let level = level_plane(plane, piece, points, up)?;
    let idx = measured_or_all(points, piece);
    let spread = |p: &Plane| {
        median(
            idx.iter()
                .map(|&i| p.inverse_depth_residual(&points[i]).abs())
                .collect(),
        )
    };
    let (own, flat) = (spread(plane)?, spread(&level)?);
    (flat.is_finite() && flat <= LEVEL_RESIDUAL_RATIO * own).then_some(level)
}

/// The level plane (normal ±`up`, on the side of `plane`'s) through the median height of the
/// measured points of `piece`, when `plane` is within [`LEVEL_MAX_TILT_DEG`] of it.
fn level_plane(plane: &Plane, piece: &[usize], points: &[Point], up: Vec3) -> Option<Plane> {
    let normal = if plane.normal.dot(up) >= 0.0 { up } else { -up };
    if plane.normal.angle_between(normal).to_degrees() > LEVEL_MAX_TILT_DEG {
        return None;
    }
    let idx = measured_or_all(points, piece);
    let offset = median(
        idx.iter()
            .map(|&i| normal.dot(points[i].p) as f64)
            .collect(),
    )? as f32;
    Some(Plane::facing_camera(normal, offset))
}

/// The median of `v` (the upper one of an even count); `None` when empty.
fn median(mut v: Vec<f64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    let k = v.len() / 2;
    Some(*v.select_nth_unstable_by(k, f64::total_cmp).1)
}

/// Largest tilt from up (degrees) of a plane that may be levelled ([`levelled`]).
const LEVEL_MAX_TILT_DEG: f32 = 10.0;

/// How much worse (median inverse-depth residual) a levelled plane may fit its points. The
/// near-horizontal planes found on 128- and 1024-spp renders of `room` and `clutter` and in the
/// noisy test room give ratios of 0.9–1.2; a board sloping 7° under that noise gives 1.6 (test
/// `a_near_horizontal_plane_is_levelled_only_when_its_tilt_is_noise`).
const LEVEL_RESIDUAL_RATIO: f64 = 1.25;

/// How many more connected inliers a level band's own fitted plane may have for the band to be a
/// level surface ([`Search::as_level`]). On the 256-spp `clutter` render the table top's band has
/// 329 points and its fitted plane 391 (1.19×, counted in the level search's pool at stop 33); a
/// band across a plane that really slopes is a small part of it.
const LEVEL_BAND_RATIO: f32 = 1.5;

/// Largest tilt from up (degrees) of a level band's fitted plane that is put down to the
/// matcher's bias ([`Search::as_level`]): 3° measured on `clutter`'s table top; the
/// steepest ramp that building codes allow (1:12) slopes 4.8°, a drawing board 10° or more.
const LEVEL_BIAS_TILT_DEG: f32 = 4.0;

fn describe(
    plane: &Plane,
    piece: &[usize],
    points: &[Point],
    camera: &Camera,
    up: Vec3,
    stride: usize,
) -> SupportSurface {
    let n = plane.normal;
    let project = |p: Vec3| p - n * (n.dot(p) - plane.offset);
    let centroid = project(piece.iter().map(|&i| points[i].p).sum::<Vec3>() / piece.len() as f32);
    let rms = (piece
        .iter()
        .map(|&i| {
            let d = (n.dot(points[i].p) - plane.offset) as f64;
            d * d
        })
        .sum::<f64>()
        / piece.len() as f64)
        .sqrt() as f32;
    // Plane basis with e1 × e2 = n, so hulls are counter-clockwise seen along −n.
    let e1 = n.any_orthonormal_vector();
    let e2 = n.cross(e1);
    let flat: Vec<Vec2> = piece
        .iter()
        .map(|&i| {
            let d = points[i].p - centroid;
            Vec2::new(d.dot(e1), d.dot(e2))
        })
        .collect();
    let hull = convex_hull(flat);
    let area = 0.5
        * hull
            .iter()
            .zip(hull.iter().cycle().skip(1))
            .map(|(a, b)| a.perp_dot(*b))
            .sum::<f32>()
            .abs();
    let polygon: Vec<Vec3> = hull
        .iter()
        .map(|q| centroid + e1 * q.x + e2 * q.y)
        .collect();
    let polygon_image = polygon
        .iter()
        .filter_map(|p| camera.project(*p).map(|(px, _)| px))
        .collect();
    let kind = SurfaceKind::relative_to(n, up);
    SupportSurface {
        normal: n,
        centroid,
        offset: plane.offset,
        inliers: piece.len() * stride,
        rms_m: rms,
        area_m2: area,
        polygon,
        polygon_image,
        kind,
    }
}

/// Convex hull (Andrew's monotone chain), counter-clockwise, without collinear points.
fn convex_hull(mut pts: Vec<Vec2>) -> Vec<Vec2> {
    pts.retain(|p| p.is_finite());
    pts.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    pts.dedup();
    if pts.len() < 3 {
        return pts;
    }
    let cross = |o: Vec2, a: Vec2, b: Vec2| (a - o).perp_dot(b - o);
    let mut lower: Vec<Vec2> = Vec::new();
    for &p in &pts {
        while lower.len() >= 2 && cross(lower[lower.len() - 2], lower[lower.len() - 1], p) <= 0.0 {
            lower.pop();
        }
        lower.push(p);
    }
    let mut upper: Vec<Vec2> = Vec::new();
    for &p in pts.iter().rev() {
        while upper.len() >= 2 && cross(upper[upper.len() - 2], upper[upper.len() - 1], p) <= 0.0 {
            upper.pop();
        }
        upper.push(p);
    }
    lower.pop();
    upper.pop();
    lower.extend(upper);
    lower
}

/// Even–odd rule.
fn point_in_polygon(p: Vec2, poly: &[Vec2]) -> bool {
    let mut inside = false;
    for (i, a) in poly.iter().enumerate() {
        let b = poly[(i + 1) % poly.len()];
        if (a.y > p.y) != (b.y > p.y) {
            let x = a.x + (p.y - a.y) / (b.y - a.y) * (b.x - a.x);
            if p.x < x {
                inside = !inside;
            }
        }
    }
    inside
}

/// A small deterministic generator (xorshift64*); quality is ample for RANSAC sampling.
pub(crate) struct XorShift(pub(crate) u64);

impl XorShift {
    pub(crate) fn next_u64(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.0 = x;
        x.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }

    pub(crate) fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    /// Uniform in [0, 1).
    #[cfg(test)]
    pub(crate) fn unit(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Members of a horizontal plane in two blocks of pixels side by side, `gap` pixels apart,
    /// the gap's pixels showing `gap_point` (only pixel positions enter the grid; the points
    /// enter the plane tests); the extent of the larger (left) block on a 200×100 image, 2-pixel
    /// cells.
    fn extent_across(gap: usize, gap_point: Vec3) -> (usize, usize) {
        let camera = Camera::from_focal(100.0, 200, 100).unwrap();
        let grid = ImageGrid::new(&camera);
        let plane = Plane::facing_camera(Vec3::Y, -1.0);
        let point = |x: usize, y: usize, p: Vec3| Point {
            p,
            n: Vec3::Y,
            px: Vec2::new(x as f32 + 0.5, y as f32 + 0.5),
            depth: -p.z,
            measured: true,
        };
        let on_plane = Vec3::new(0.0, -1.0, -3.0);
        let (left, right) = (10..50, 50 + gap..80 + gap);
        let mut points = Vec::new();
        let mut members = Vec::new();
        for y in 40..60 {
            for x in left.clone().chain(right.clone()) {
                members.push(points.len());
                points.push(point(x, y, on_plane));
            }
            for x in 50..50 + gap {
                points.push(point(x, y, gap_point));
            }
        }
        let tolerance = Tolerance {
            relative: 0.01,
            inverse_depth: 0.0,
            cos_normal: 30f32.to_radians().cos(),
        };
        let extent = grid.extent(&points, &members, &plane, &tolerance, 1);
        let on_right = extent
            .iter()
            .filter(|&&i| points[i].px.x >= (50 + gap) as f32)
            .count();
        (extent.len() - on_right, on_right)
    }

    #[test]
    fn vectorised_scoring_counts_exactly_the_points_a_plane_accepts() {
        let mut rng = XorShift(0x5c0e);
        let unit_vector = |rng: &mut XorShift| {
            let v = Vec3::new(rng.unit(), rng.unit(), rng.unit()) * 2.0 - 1.0;
            v.try_normalize().unwrap_or(Vec3::Y)
        };
        // Points scattered about a floor, many of them near the tolerance's edges; 1003 of them,
        // so that the vector loop has a tail.
        let points: Vec<Point> = (0..1003)
            .map(|k| {
                let p = Vec3::new(
                    rng.unit() * 4.0 - 2.0,
                    -1.3 + (rng.unit() - 0.5) * 0.06,
                    -1.0 - rng.unit() * 5.0,
                );
                let n = if k % 3 == 0 {
                    unit_vector(&mut rng)
                } else {
                    (Vec3::Y + unit_vector(&mut rng) * 0.3).normalize()
                };
                Point {
                    p,
                    n,
                    px: Vec2::ZERO,
                    depth: -p.z,
                    measured: true,
                }
            })
            .collect();
        let sample = ScoreSample::new(&points, 0..points.len());
        let mut partial = 0;
        for round in 0..200 {
            let plane = Plane::facing_camera(
                (Vec3::Y + unit_vector(&mut rng) * 0.02).normalize(),
                -1.3 + (rng.unit() - 0.5) * 0.04,
            );
            let tolerance = Tolerance {
                relative: 0.005 + rng.unit() * 0.02,
                inverse_depth: if round % 2 == 0 {
                    0.0
                } else {
                    rng.unit() * 0.05
                },
                cos_normal: (rng.unit() * 40.0).to_radians().cos(),
            };
            let plain = points
                .iter()
                .filter(|q| plane.accepts(q, &tolerance))
                .count();
            assert_eq!(
                count_accepted(&sample, &plane, &tolerance),
                plain,
                "round {round}"
            );
            assert_eq!(sample.count_accepted_body(&plane, &tolerance), plain);
            partial += (plain * 10 > points.len() && plain * 10 < points.len() * 9) as usize;
        }
        // Most planes accept some of the points and reject others: the edges are exercised.
        assert!(
            partial > 100,
            "{partial} of 200 planes accept 10–90 % of the points"
        );
    }

    #[test]
    fn a_surface_joins_a_piece_across_a_short_hidden_gap_only() {
        // Above the plane, between it and the camera: it hides the plane.
        let hiding = Vec3::new(0.0, -0.5, -3.0);
        // Below the plane: the camera sees past where the plane would be.
        let beyond = Vec3::new(0.0, -1.5, -3.0);
        assert_eq!(
            extent_across(16, hiding),
            (800, 600),
            "8 hidden cells are crossed"
        );
        assert_eq!(
            extent_across(40, hiding),
            (800, 0),
            "20 cells are more than MAX_BRIDGE_CELLS"
        );
        assert_eq!(
            extent_across(4, beyond),
            (800, 0),
            "a view past the plane cuts it"
        );
    }

    #[test]
    fn hull_and_point_in_polygon() {
        let pts = vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(2.0, 0.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(2.0, 2.0),
            Vec2::new(0.0, 2.0),
        ];
        let hull = convex_hull(pts);
        assert_eq!(hull.len(), 4);
        assert!(point_in_polygon(Vec2::new(1.0, 1.5), &hull));
        assert!(!point_in_polygon(Vec2::new(3.0, 1.0), &hull));
    }
}
