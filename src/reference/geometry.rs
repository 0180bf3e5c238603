//! The scene's triangles in world space, their shading attributes, and ray queries over an obvhs
//! compressed wide BVH (CWBVH).

use glam::{Mat3, Vec3, Vec3A};
use obvhs::cwbvh::CwBvh;
use obvhs::ray::RayHit;
use obvhs::triangle::Triangle;
use obvhs::BvhBuildParams;
use std::time::Duration;

use super::description::{Material, Object};
use super::shapes::tessellate;
use super::textures;
use crate::error::{Error, Result};
use crate::mesh::bvh::obvhs_ray;

/// The most triangles a scene may have (about 3 GB of triangles and attributes).
pub const MAX_TRIANGLES: usize = 20_000_000;

/// Shading attributes of one triangle (original order).
#[derive(Debug, Clone, Copy)]
pub(crate) struct TriangleAttributes {
    pub normals: [Vec3A; 3],
    /// Object-space positions times the object's scale: where solid textures are evaluated.
    pub texture_points: [Vec3A; 3],
    pub object: u32,
}

/// What a ray hit.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SurfaceHit {
    pub t: f32,
    /// Index into the original triangle list.
    pub triangle: u32,
}

/// A surface point ready for shading.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SurfacePoint {
    pub position: Vec3A,
    /// Geometric normal, unit, on the side the ray came from.
    pub geometric_normal: Vec3A,
    /// Interpolated normal, unit, on the same side as the geometric one.
    pub shading_normal: Vec3A,
    pub object: u32,
    pub base_color: Vec3A,
}

/// Triangles, attributes and BVH of a scene.
pub(crate) struct Geometry {
    bvh: Option<CwBvh>,
    /// Triangles in BVH order (so that leaves index them directly).
    bvh_triangles: Vec<Triangle>,
    /// BVH order → original index.
    original: Vec<u32>,
    triangles: Vec<Triangle>,
    attributes: Vec<TriangleAttributes>,
    materials: Vec<Material>,
    /// Objects flagged as inserted (for composites).
    inserted: Vec<bool>,
}

impl Geometry {
    /// Tessellates and transforms every object and builds the BVH. `inserted[i]` marks objects
    /// that are counted in the composite's object mask.
    ///
    /// # Errors
    /// `TooLarge` over [`MAX_TRIANGLES`].
    pub(crate) fn build(objects: &[(&Object, bool)]) -> Result<Geometry> {
        let mut triangles = Vec::new();
        let mut attributes = Vec::new();
        let mut materials = Vec::new();
        let mut inserted = Vec::new();
        for (index, (object, is_inserted)) in objects.iter().enumerate() {
            let mesh = tessellate(&object.shape);
            if triangles.len() + mesh.indices.len() > MAX_TRIANGLES {
                return Err(Error::TooLarge(format!(
                    "scene has more than {MAX_TRIANGLES} triangles (object {index})"
                )));
            }
            let m = object.transform.matrix();
            let normal_matrix = Mat3::from_mat4(m).inverse().transpose();
            let scale = Vec3::from(object.transform.scale);
            for tri in &mesh.indices {
                let p = tri.map(|i| Vec3A::from(m.transform_point3(mesh.positions[i as usize])));
                let n = tri.map(|i| {
                    let n =
                        Vec3A::from(normal_matrix * mesh.normals[i as usize]).normalize_or_zero();
                    if n == Vec3A::ZERO {
                        (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero()
                    } else {
                        n
                    }
                });
                let texture_points = tri.map(|i| Vec3A::from(mesh.positions[i as usize] * scale));
                triangles.push(Triangle {
                    v0: p[0],
                    v1: p[1],
                    v2: p[2],
                });
                attributes.push(TriangleAttributes {
                    normals: n,
                    texture_points,
                    object: index as u32,
                });
            }
            materials.push(object.material.clone());
            inserted.push(*is_inserted);
        }
        let (bvh, bvh_triangles, original) = if triangles.is_empty() {
            (None, Vec::new(), Vec::new())
        } else {
            let bvh = obvhs::cwbvh::builder::build_cwbvh_from_tris(
                &triangles,
                BvhBuildParams::medium_build(),
                &mut Duration::default(),
            );
            let bvh_triangles = bvh
                .primitive_indices
                .iter()
                .map(|i| triangles[*i as usize])
                .collect();
            let original = bvh.primitive_indices.clone();
            (Some(bvh), bvh_triangles, original)
        };
        Ok(Geometry {
            bvh,
            bvh_triangles,
            original,
            triangles,
            attributes,
            materials,
            inserted,
        })
    }

    pub(crate) fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    pub(crate) fn material(&self, object: u32) -> &Material {
        &self.materials[object as usize]
    }

    pub(crate) fn is_inserted(&self, object: u32) -> bool {
        self.inserted[object as usize]
    }

    pub(crate) fn triangle(&self, index: u32) -> &Triangle {
        &self.triangles[index as usize]
    }

    /// Nearest hit along `o + t·d`, `t` in (0, tmax).
    pub(crate) fn intersect(&self, o: Vec3A, d: Vec3A, tmax: f32) -> Option<SurfaceHit> {
        let bvh = self.bvh.as_ref()?;
        let ray = obvhs_ray(o, d, tmax);
        let mut hit = RayHit::none();
        if bvh.ray_traverse(ray, &mut hit, |r, id| self.bvh_triangles[id].intersect(r)) {
            Some(SurfaceHit {
                t: hit.t,
                triangle: self.original[hit.primitive_id as usize],
            })
        } else {
            None
        }
    }

    /// Whether anything lies along `o + t·d` for `t` in (0, tmax).
    pub(crate) fn occluded(&self, o: Vec3A, d: Vec3A, tmax: f32) -> bool {
        let Some(bvh) = self.bvh.as_ref() else {
            return false;
        };
        let ray = obvhs_ray(o, d, tmax);
        !bvh.ray_traverse_miss(ray, |r, id| self.bvh_triangles[id].intersect(r))
    }

    /// Interpolated attributes at a hit, normals turned towards the incoming ray `d`.
    pub(crate) fn surface_point(&self, o: Vec3A, d: Vec3A, hit: SurfaceHit) -> SurfacePoint {
        let tri = &self.triangles[hit.triangle as usize];
        let attr = &self.attributes[hit.triangle as usize];
        let (b1, b2) = barycentrics(tri, o, d);
        let b0 = 1.0 - b1 - b2;
        let position = tri.v0 * b0 + tri.v1 * b1 + tri.v2 * b2;
        let mut ng = (tri.v1 - tri.v0).cross(tri.v2 - tri.v0).normalize_or_zero();
        if ng.dot(d) > 0.0 {
            ng = -ng;
        }
        let mut ns = (attr.normals[0] * b0 + attr.normals[1] * b1 + attr.normals[2] * b2)
            .normalize_or_zero();
        if ns == Vec3A::ZERO {
            ns = ng;
        } else if ns.dot(ng) < 0.0 {
            ns = -ns;
        }
        let material = &self.materials[attr.object as usize];
        let base = Vec3A::from(material.base_color);
        let base_color = match &material.texture {
            Some(t) => {
                let tp = attr.texture_points[0] * b0
                    + attr.texture_points[1] * b1
                    + attr.texture_points[2] * b2;
                textures::evaluate(t, base, tp)
            }
            None => base,
        };
        SurfacePoint {
            position,
            geometric_normal: ng,
            shading_normal: ns,
            object: attr.object,
            base_color,
        }
    }
}

/// Barycentric coordinates (of v1, v2) of the ray's crossing of the triangle's plane
/// (Möller-Trumbore).
fn barycentrics(tri: &Triangle, o: Vec3A, d: Vec3A) -> (f32, f32) {
    let e1 = tri.v1 - tri.v0;
    let e2 = tri.v2 - tri.v0;
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det.abs() < f32::MIN_POSITIVE {
        return (1.0 / 3.0, 1.0 / 3.0);
    }
    let inv = 1.0 / det;
    let s = o - tri.v0;
    let u = s.dot(p) * inv;
    let q = s.cross(e1);
    let v = d.dot(q) * inv;
    (u.clamp(0.0, 1.0), v.clamp(0.0, 1.0 - u.clamp(0.0, 1.0)))
}

/// Ray parameter of the crossing of `o + t·d` with the plane of `tri`, in f64: the exact depth of
/// a primary hit for the ground truth, free of the BVH's f32 rounding.
pub(crate) fn plane_distance_f64(tri: &Triangle, o: [f64; 3], d: [f64; 3]) -> f64 {
    let v = |a: Vec3A| [a.x as f64, a.y as f64, a.z as f64];
    let (a, b, c) = (v(tri.v0), v(tri.v1), v(tri.v2));
    let sub = |x: [f64; 3], y: [f64; 3]| [x[0] - y[0], x[1] - y[1], x[2] - y[2]];
    let cross = |x: [f64; 3], y: [f64; 3]| {
        [
            x[1] * y[2] - x[2] * y[1],
            x[2] * y[0] - x[0] * y[2],
            x[0] * y[1] - x[1] * y[0],
        ]
    };
    let dot = |x: [f64; 3], y: [f64; 3]| x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
    let n = cross(sub(b, a), sub(c, a));
    dot(n, sub(a, o)) / dot(n, d)
}
