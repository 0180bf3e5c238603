//! Ray queries over the scene mesh with obvhs' compressed wide BVH (CWBVH): closest hit (pick a
//! pixel → 3D point, normal, distance) and any-hit occlusion, one at a time or batched in parallel.

use std::time::Duration;

use glam::{Vec2, Vec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::{builder::build_cwbvh, CwBvh};
use obvhs::ray::RayHit;
use obvhs::triangle::Triangle;
use obvhs::{Boundable, BvhBuildParams};
use rayon::prelude::*;

use super::SceneMesh;
use crate::camera::Camera;

/// A ray: origin and direction (any length > 0; hits report `t` in units of that length) and the
/// largest `t` of interest.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    /// Start point, metres.
    pub origin: Vec3,
    /// Direction; need not be unit length.
    pub direction: Vec3,
    /// Hits beyond `origin + t_max · direction` are ignored (`f32::INFINITY` for none).
    pub t_max: f32,
}

impl Ray {
    /// A ray without a far limit.
    pub fn new(origin: Vec3, direction: Vec3) -> Ray {
        Ray {
            origin,
            direction,
            t_max: f32::INFINITY,
        }
    }

    fn to_obvhs(self) -> obvhs::ray::Ray {
        obvhs_ray(self.origin.into(), self.direction.into(), self.t_max)
    }

    fn is_valid(&self) -> bool {
        self.origin.is_finite()
            && self.direction.is_finite()
            && self.direction.length_squared() > 0.0
            && !self.t_max.is_nan()
            && self.t_max > 0.0
    }
}

/// Where a ray meets the mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Ray parameter: `point = origin + t · direction`.
    pub t: f32,
    /// The hit point, metres.
    pub point: Vec3,
    /// Unit normal of the triangle hit, facing the ray's origin.
    pub geometric_normal: Vec3,
    /// Unit smooth normal interpolated from the mesh's vertex normals, facing the ray's origin;
    /// equal to `geometric_normal` when the mesh has no normals.
    pub normal: Vec3,
    /// Index of the triangle hit (into `SceneMesh::indices / 3`).
    pub triangle: u32,
    /// Barycentric coordinates of the hit: weights of the triangle's 2nd and 3rd corners.
    pub barycentric: Vec2,
}

/// A bounding-volume hierarchy over a triangle mesh. Read-only after construction and `Sync`, so
/// one `Bvh` can serve many threads.
pub struct Bvh {
    bvh: Option<CwBvh>,
    triangles: Vec<Triangle>,
    /// Per-triangle vertex normals (for smooth hit normals), when the mesh has them.
    corner_normals: Vec<[Vec3; 3]>,
}

impl std::fmt::Debug for Bvh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bvh")
            .field("triangles", &self.triangles.len())
            .finish()
    }
}

impl Bvh {
    /// Builds the hierarchy over a scene mesh. Triangles with a non-finite corner are left out;
    /// an empty mesh gives a BVH that no ray hits.
    pub fn new(mesh: &SceneMesh) -> Bvh {
        let normals_ok = mesh.normals.len() == mesh.positions.len();
        let mut triangles = Vec::with_capacity(mesh.triangle_count());
        let mut corner_normals = Vec::new();
        for t in mesh.indices.chunks_exact(3) {
            let Some(corners) = t
                .iter()
                .map(|&i| mesh.positions.get(i as usize).map(|p| Vec3::from(*p)))
                .collect::<Option<Vec<_>>>()
            else {
                continue;
            };
            if !corners.iter().all(|p| p.is_finite()) {
                continue;
            }
            triangles.push(Triangle {
                v0: corners[0].into(),
                v1: corners[1].into(),
                v2: corners[2].into(),
            });
            if normals_ok {
                corner_normals.push([0, 1, 2].map(|k| Vec3::from(mesh.normals[t[k] as usize])));
            }
        }
        Bvh::from_parts(triangles, corner_normals)
    }

    /// Builds the hierarchy over bare triangles (three corners each), e.g. the scene plus
    /// inserted artefacts.
    pub fn from_triangles(triangles: &[[Vec3; 3]]) -> Bvh {
        let triangles = triangles
            .iter()
            .filter(|t| t.iter().all(|p| p.is_finite()))
            .map(|t| Triangle {
                v0: t[0].into(),
                v1: t[1].into(),
                v2: t[2].into(),
            })
            .collect();
        Bvh::from_parts(triangles, Vec::new())
    }

    fn from_parts(triangles: Vec<Triangle>, corner_normals: Vec<[Vec3; 3]>) -> Bvh {
        let bvh = (!triangles.is_empty()).then(|| {
            let padded: Vec<PaddedTriangle> =
                triangles.iter().map(|t| PaddedTriangle(*t)).collect();
            build_cwbvh(
                &padded,
                BvhBuildParams::medium_build(),
                &mut Duration::default(),
            )
        });
        Bvh {
            bvh,
            triangles,
            corner_normals,
        }
    }

    /// Number of triangles in the hierarchy.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// The nearest hit along the ray within `(0, t_max]`, or `None` (also for a ray with a
    /// non-finite or zero direction).
    pub fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        let bvh = self.bvh.as_ref()?;
        if !ray.is_valid() {
            return None;
        }
        let r = ray.to_obvhs();
        let mut hit = RayHit::none();
        let found = bvh.ray_traverse(r, &mut hit, |r, id| {
            intersect_closed(&self.triangles[bvh.primitive_indices[id] as usize], r)
        });
        if !found {
            return None;
        }
        let index = bvh.primitive_indices[hit.primitive_id as usize] as usize;
        let tri = &self.triangles[index];
        let bary = tri.compute_barycentric(&r);
        let point = ray.origin + ray.direction * hit.t;
        let mut geometric = Vec3::from(tri.compute_normal());
        if geometric.dot(ray.direction) > 0.0 {
            geometric = -geometric;
        }
        let normal = match self.corner_normals.get(index) {
            Some(n) => {
                let smooth = n[0] * (1.0 - bary.x - bary.y) + n[1] * bary.x + n[2] * bary.y;
                let smooth = smooth.normalize_or(geometric);
                // Faced towards the ray's origin, not towards the triangle's side: on a stereo
                // mesh the triangle normal at pixel spacing is dominated by depth noise (it can
                // sit more than 90° from the fitted vertex normals on a floor seen at a grazing
                // angle), and following it would turn correct smooth normals upside down.
                if smooth.dot(ray.direction) > 0.0 {
                    -smooth
                } else {
                    smooth
                }
            }
            None => geometric,
        };
        Some(Hit {
            t: hit.t,
            point,
            geometric_normal: geometric,
            normal,
            triangle: index as u32,
            barycentric: bary,
        })
    }

    /// Whether anything lies along the ray within `(0, t_max)` (shadow rays): stops at the first
    /// hit found, not the nearest.
    pub fn occluded(&self, ray: &Ray) -> bool {
        let Some(bvh) = self.bvh.as_ref() else {
            return false;
        };
        if !ray.is_valid() {
            return false;
        }
        let r = ray.to_obvhs();
        !bvh.ray_traverse_miss(r, |r, id| {
            intersect_closed(&self.triangles[bvh.primitive_indices[id] as usize], r)
        })
    }

    /// [`Bvh::closest_hit`] for many rays, in parallel (rayon).
    pub fn closest_hits(&self, rays: &[Ray]) -> Vec<Option<Hit>> {
        rays.par_iter().map(|r| self.closest_hit(r)).collect()
    }

    /// [`Bvh::occluded`] for many rays, in parallel (rayon).
    pub fn occluded_batch(&self, rays: &[Ray]) -> Vec<bool> {
        rays.par_iter().map(|r| self.occluded(r)).collect()
    }
}

/// obvhs' ray from `origin` along `direction` up to `t_max`. A direction component of −0.0
/// becomes +0.0: obvhs takes the traversal order from `direction < 0` but the inverse direction
/// from the sign bit, so a negative zero swaps a box's near and far planes and axis-aligned rays
/// (a host's ray straight down, a shadow ray towards a sun straight overhead) miss everything.
pub(crate) fn obvhs_ray(origin: Vec3A, direction: Vec3A, t_max: f32) -> obvhs::ray::Ray {
    obvhs::ray::Ray::new(origin, direction + Vec3A::ZERO, 0.0, t_max)
}

/// The ray of the camera through image position `pixel` (continuous pixels: the centre of pixel
/// `(x, y)` is `(x + 0.5, y + 0.5)`).
pub fn camera_ray(camera: &Camera, pixel: Vec2) -> Ray {
    Ray::new(Vec3::ZERO, camera.ray_direction(pixel.x, pixel.y))
}

/// Picks the scene surface seen at `pixel`: the 3D point, its normal and its distance from the
/// camera (`Hit::t`, metres, because the camera ray is unit length). `None` where the mesh has a
/// hole or the pixel is not finite.
pub fn pick(bvh: &Bvh, camera: &Camera, pixel: Vec2) -> Option<Hit> {
    if !pixel.is_finite() {
        return None;
    }
    bvh.closest_hit(&camera_ray(camera, pixel))
}

/// Barycentric slack of [`intersect_closed`], relative (a triangle grows by this fraction of itself):
/// above the f32 rounding of barycentrics for triangles a few metres from the origin.
const EDGE_SLACK: f32 = 1e-4;

/// A triangle whose bounding box is grown a little. The scene mesh's grid makes boxes that abut
/// exactly (and flat ones, for planes facing an axis); a ray along a shared boundary can then
/// fall between two boxes through rounding in the slab test. Growing each box by a fraction of
/// its coordinates' magnitude closes those gaps at no measurable cost.
struct PaddedTriangle(Triangle);

impl Boundable for PaddedTriangle {
    fn aabb(&self) -> Aabb {
        let b = self.0.aabb();
        let scale = b.min.abs().max(b.max.abs()).max_element().max(1e-3);
        let pad = glam::Vec3A::splat(scale * 1e-5);
        Aabb::new(b.min - pad, b.max + pad)
    }
}

/// Möller–Trumbore with closed, slightly widened edges: the distance along `ray` to the triangle,
/// or infinity.
///
/// obvhs' own test rejects barycentrics of −0.0 by their sign bit, so a ray through a shared vertex
/// or along a shared edge can miss *both* triangles. The scene mesh puts its vertices exactly at
/// pixel centres, where hosts pick, so edges must be closed: a tiny overlap (a double hit on an
/// edge is harmless for closest-hit and any-hit) is far better than a hole.
fn intersect_closed(tri: &Triangle, ray: &obvhs::ray::Ray) -> f32 {
    let e1 = tri.v1 - tri.v0;
    let e2 = tri.v2 - tri.v0;
    let p = ray.direction.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 || !det.is_finite() {
        return f32::INFINITY;
    }
    let inv_det = 1.0 / det;
    let s = ray.origin - tri.v0;
    let u = s.dot(p) * inv_det;
    let q = s.cross(e1);
    let v = ray.direction.dot(q) * inv_det;
    if u < -EDGE_SLACK || v < -EDGE_SLACK || u + v > 1.0 + EDGE_SLACK {
        return f32::INFINITY;
    }
    let t = e2.dot(q) * inv_det;
    if t >= ray.tmin && t <= ray.tmax {
        t
    } else {
        f32::INFINITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::Raster;
    use crate::mesh::MeshOptions;

    /// Rays through shared vertices and along shared edges (exactly where the grid puts them:
    /// pixel centres and half-way between) must hit; obvhs' own test misses some of them.
    #[test]
    fn picks_at_vertices_and_edges_never_fall_through() {
        let camera = Camera::from_focal(60.0, 64, 48).unwrap();
        for (name, depth) in [
            ("fronto-parallel wall", Raster::filled(64, 48, 8.0)),
            (
                "slanted plane",
                Raster::from_fn(64, 48, |x, y| 3.0 + 0.02 * x as f32 + 0.05 * y as f32),
            ),
        ] {
            let mesh = SceneMesh::from_depth(&depth, &camera, &MeshOptions::default()).unwrap();
            let bvh = Bvh::new(&mesh);
            let mut misses = Vec::new();
            // The mesh spans pixel centres 0.5 … w − 0.5; stay one pixel inside its border, where
            // a ray through the outermost vertex may round either way.
            for y in 1..46 {
                for x in 1..62 {
                    for (dx, dy) in [(0.5, 0.5), (1.0, 1.0), (1.0, 0.5), (0.5, 1.0)] {
                        let pixel = Vec2::new(x as f32 + dx, y as f32 + dy);
                        if pick(&bvh, &camera, pixel).is_none() {
                            misses.push(pixel);
                        }
                    }
                }
            }
            assert!(
                misses.is_empty(),
                "{name}: {} picks fell through, e.g. {:?}",
                misses.len(),
                &misses[..misses.len().min(5)]
            );
        }
    }

    #[test]
    fn smooth_normal_faces_the_ray_even_against_a_noisy_triangle() {
        // A triangle seen almost edge-on whose facet leans one way while its (fitted) vertex
        // normals lean the other — both towards the camera at the origin, more than 90° apart:
        // what a stereo floor's pixel-sized triangles do under depth noise.
        let facet = Vec3::new(0.0, -1.0, 0.1).normalize();
        let fitted = Vec3::new(0.0, 1.0, 0.1).normalize();
        assert!(facet.dot(fitted) < 0.0);
        // Two edges perpendicular to `facet`, around the point (0, 0, −2).
        let e1 = Vec3::X;
        let e2 = facet.cross(e1).normalize();
        let c = Vec3::new(0.0, 0.0, -2.0);
        let corners = [c - 0.5 * e1 - 0.5 * e2, c + 0.5 * e1 - 0.5 * e2, c + e2];
        let mesh = SceneMesh {
            positions: corners.map(|p| p.to_array()).to_vec(),
            normals: vec![fitted.to_array(); 3],
            uvs: vec![[0.0; 2]; 3],
            indices: vec![0, 1, 2],
            ..SceneMesh::default()
        };
        let hit = Bvh::new(&mesh)
            .closest_hit(&Ray::new(Vec3::ZERO, -Vec3::Z))
            .unwrap();
        assert!(hit.geometric_normal.angle_between(facet).to_degrees() < 0.01);
        assert!(
            hit.normal.angle_between(fitted).to_degrees() < 0.01,
            "smooth normal {} (fitted {fitted})",
            hit.normal
        );
    }

    #[test]
    fn bvh_is_shareable_between_threads() {
        fn is_sync<T: Sync + Send>() {}
        is_sync::<Bvh>();
    }

    #[test]
    fn pick_on_a_slanted_plane_returns_the_analytic_point() {
        let camera = Camera::from_focal(300.0, 120, 90).unwrap();
        let n = Vec3::new(0.2, 0.6, 0.8).normalize();
        let d = -2.5; // n·p = d
        let depth = Raster::from_fn(120, 90, |x, y| {
            let dir = camera
                .unproject(x as f32 + 0.5, y as f32 + 0.5, 1.0)
                .unwrap();
            d / n.dot(dir)
        });
        let mesh = SceneMesh::from_depth(&depth, &camera, &MeshOptions::default()).unwrap();
        let bvh = Bvh::new(&mesh);
        for pixel in [
            Vec2::new(60.3, 45.7),
            Vec2::new(10.0, 80.2),
            Vec2::new(111.9, 3.1),
        ] {
            let hit = pick(&bvh, &camera, pixel).unwrap();
            let dir = camera.ray_direction(pixel.x, pixel.y);
            let t = d / n.dot(dir);
            let truth = dir * t;
            assert!(
                (hit.point - truth).length() < 1e-4 * t,
                "{} vs {truth}",
                hit.point
            );
            assert!((hit.t - t).abs() < 1e-4 * t);
            assert!(hit.normal.angle_between(n).to_degrees() < 0.05);
            assert!(hit.geometric_normal.angle_between(n).to_degrees() < 0.05);
        }
        // Outside the image the plane's mesh ends: a ray far off misses.
        assert!(pick(&bvh, &camera, Vec2::new(-500.0, 45.0)).is_none());
        assert!(pick(&bvh, &camera, Vec2::new(f32::NAN, 45.0)).is_none());
    }

    #[test]
    fn occlusion_and_batches_agree_with_single_queries() {
        let camera = Camera::from_focal(100.0, 40, 40).unwrap();
        let depth = Raster::filled(40, 40, 2.0);
        let mesh = SceneMesh::from_depth(&depth, &camera, &MeshOptions::default()).unwrap();
        let bvh = Bvh::new(&mesh);
        let toward_wall = Ray {
            origin: Vec3::new(0.0, 0.0, -1.0),
            direction: Vec3::NEG_Z,
            t_max: 5.0,
        };
        assert!(bvh.occluded(&toward_wall));
        assert!(!bvh.occluded(&Ray {
            t_max: 0.9,
            ..toward_wall
        }));
        assert!(!bvh.occluded(&Ray {
            direction: Vec3::Z,
            ..toward_wall
        }));
        assert!(!bvh.occluded(&Ray {
            direction: Vec3::ZERO,
            ..toward_wall
        }));
        let rays: Vec<Ray> = (0..200)
            .map(|i| {
                let a = i as f32 * 0.05;
                Ray::new(Vec3::ZERO, Vec3::new(a.sin() * 0.3, a.cos() * 0.3, -1.0))
            })
            .collect();
        let hits = bvh.closest_hits(&rays);
        let occl = bvh.occluded_batch(&rays);
        for ((r, h), o) in rays.iter().zip(&hits).zip(&occl) {
            assert_eq!(*h, bvh.closest_hit(r));
            assert_eq!(h.is_some(), *o);
            if let Some(h) = h {
                assert!((h.point.z + 2.0).abs() < 1e-5);
            }
        }
        // Axis-aligned rays with negative-zero components (a host's ray straight down).
        let straight = Ray::new(Vec3::new(0.1, 0.2, 0.0), Vec3::new(-0.0, -0.0, -1.0));
        assert!(bvh.closest_hit(&straight).is_some());
        assert!(bvh.occluded(&straight));
        let empty = Bvh::from_triangles(&[]);
        assert!(empty.closest_hit(&toward_wall).is_none());
        assert!(!empty.occluded(&toward_wall));
    }

    #[test]
    fn closest_hit_takes_the_nearer_of_two_layers() {
        let quad = |z: f32| {
            [
                [
                    Vec3::new(-1.0, -1.0, z),
                    Vec3::new(1.0, -1.0, z),
                    Vec3::new(1.0, 1.0, z),
                ],
                [
                    Vec3::new(-1.0, -1.0, z),
                    Vec3::new(1.0, 1.0, z),
                    Vec3::new(-1.0, 1.0, z),
                ],
            ]
        };
        let mut tris = quad(-3.0).to_vec();
        tris.extend(quad(-2.0));
        let bvh = Bvh::from_triangles(&tris);
        let hit = bvh
            .closest_hit(&Ray::new(Vec3::ZERO, Vec3::new(0.1, 0.1, -1.0)))
            .unwrap();
        assert!((hit.t - 2.0).abs() < 1e-5);
        assert!((hit.geometric_normal - Vec3::Z).length() < 1e-6);
    }
}
