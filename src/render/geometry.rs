//! Artefacts and the scene mesh flattened into one world-space vertex list with draw ranges.
//!
//! Vertices are transformed on the CPU (instances are few and small compared with a frame's
//! pixels), so every pass uses one vertex layout and one camera/light matrix.

use std::collections::HashMap;
use std::sync::Arc;

use bytemuck::{Pod, Zeroable};
use glam::{Mat3, Vec3, Vec4};

use crate::artefact::{Aabb, AlphaMode, Artefact, ArtefactSet};
use crate::mesh::SceneMesh;

/// One vertex as the shaders read it (76 bytes, attributes packed in this order).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub(crate) struct Vertex {
    pub position: [f32; 3],
    /// 1 when the surface receives shadows, 0 when not.
    pub receives_shadow: f32,
    pub normal: [f32; 3],
    /// xyz tangent, w bitangent sign; all zero when the primitive has none.
    pub tangent: [f32; 4],
    pub uv0: [f32; 2],
    pub uv1: [f32; 2],
    pub color: [f32; 4],
}

/// One draw: a range of `indices` with one material.
#[derive(Debug, Clone)]
pub(crate) struct Draw {
    pub first_index: u32,
    pub index_count: u32,
    /// Key of the material (asset pointer, material index); `None` = default material.
    pub material: Option<MaterialKey>,
    pub blend: bool,
    pub double_sided: bool,
    pub casts_shadow: bool,
    /// Distance of the primitive's bounds centre from the camera, for back-to-front sorting.
    pub view_distance: f32,
}

/// Identifies a material of a shared asset.
pub(crate) type MaterialKey = (usize, usize);

/// Everything drawn, in world space (= the camera frame).
#[derive(Debug, Default)]
pub(crate) struct SceneGeometry {
    pub vertices: Vec<Vertex>,
    pub indices: Vec<u32>,
    /// Artefact draws (opaque and mask first in submission order, blend ones sorted far → near).
    pub draws: Vec<Draw>,
    /// Index range of the scene mesh, if any.
    pub scene_range: Option<(u32, u32)>,
    /// World bounds of visible artefacts.
    pub artefact_bounds: Option<Aabb>,
    /// World bounds of visible, shadow-casting artefacts.
    pub caster_bounds: Option<Aabb>,
    /// World bounds of the scene mesh.
    pub scene_bounds: Option<Aabb>,
    /// Each visible artefact as a sphere of equal volume: centre and radius (ambient occlusion).
    pub occluder_spheres: Vec<[f32; 4]>,
    /// The assets in use, by pointer, for material and texture upload.
    pub assets: HashMap<usize, Arc<Artefact>>,
}

fn union(a: Option<Aabb>, b: Aabb) -> Option<Aabb> {
    Some(match a {
        Some(a) => a.union(&b),
        None => b,
    })
}

impl SceneGeometry {
    pub fn build(artefacts: &ArtefactSet, scene: Option<&SceneMesh>) -> SceneGeometry {
        let mut g = SceneGeometry::default();
        for (_, instance) in artefacts.iter().filter(|(_, i)| i.visible) {
            let asset = &instance.artefact;
            if asset.is_empty() {
                continue;
            }
            let key = Arc::as_ptr(asset) as usize;
            g.assets.insert(key, asset.clone());
            let m = instance.transform;
            let linear = Mat3::from_mat4(m);
            let det = linear.determinant();
            // The inverse transpose keeps normals perpendicular under non-uniform scale; a
            // singular transform (scale 0) has none, and the plain matrix is the best guess.
            let normal_matrix = if det.abs() > f32::MIN_POSITIVE && linear.inverse().is_finite() {
                linear.inverse().transpose()
            } else {
                linear
            };
            let mirrored = det < 0.0;
            for p in &asset.primitives {
                let material = asset.materials.get(p.material);
                let base = g.vertices.len() as u32;
                for (k, pos) in p.positions.iter().enumerate() {
                    let n = p.normals.get(k).copied().unwrap_or(Vec3::Y);
                    let t = p.tangents.as_ref().and_then(|t| t.get(k).copied());
                    let tangent = match t {
                        Some(t) => {
                            let dir = (linear * t.truncate()).normalize_or_zero();
                            let w = if mirrored { -t.w } else { t.w };
                            dir.extend(w).to_array()
                        }
                        None => [0.0; 4],
                    };
                    let uv = |set: &Option<Vec<glam::Vec2>>| {
                        set.as_ref()
                            .and_then(|u| u.get(k))
                            .map(|u| u.to_array())
                            .unwrap_or([0.0; 2])
                    };
                    let color = p
                        .colors
                        .as_ref()
                        .and_then(|c| c.get(k).copied())
                        .unwrap_or(Vec4::ONE);
                    let world = m.transform_point3(*pos);
                    g.vertices.push(Vertex {
                        position: finite_or_zero(world).to_array(),
                        receives_shadow: if instance.receives_shadow { 1.0 } else { 0.0 },
                        normal: (normal_matrix * n).normalize_or(Vec3::Y).to_array(),
                        tangent,
                        uv0: uv(&p.uv0),
                        uv1: uv(&p.uv1),
                        color: color.to_array(),
                    });
                }
                let first_index = g.indices.len() as u32;
                for tri in p.indices.chunks_exact(3) {
                    if mirrored {
                        g.indices
                            .extend_from_slice(&[base + tri[0], base + tri[2], base + tri[1]]);
                    } else {
                        g.indices
                            .extend_from_slice(&[base + tri[0], base + tri[1], base + tri[2]]);
                    }
                }
                let bounds = p.bounds.transformed(&m);
                let blend = matches!(material.map(|m| m.alpha_mode), Some(AlphaMode::Blend));
                g.draws.push(Draw {
                    first_index,
                    index_count: g.indices.len() as u32 - first_index,
                    material: material.map(|_| (key, p.material)),
                    blend,
                    double_sided: material.map(|m| m.double_sided).unwrap_or(false),
                    casts_shadow: instance.casts_shadow,
                    view_distance: bounds.center().length(),
                });
            }
            let wb = instance.world_bounds();
            g.artefact_bounds = union(g.artefact_bounds, wb);
            if instance.casts_shadow {
                g.caster_bounds = union(g.caster_bounds, wb);
            }
            let half = wb.size() * 0.5;
            let radius = (half.x.max(0.0) * half.y.max(0.0) * half.z.max(0.0)).cbrt();
            let c = wb.center();
            if radius.is_finite() && c.is_finite() {
                g.occluder_spheres.push([c.x, c.y, c.z, radius]);
            }
        }
        // Opaque and masked first (any order, the depth test sorts them), then blended ones far
        // to near so each is composited over what lies behind it.
        g.draws.sort_by(|a, b| {
            a.blend.cmp(&b.blend).then(if a.blend {
                b.view_distance.total_cmp(&a.view_distance)
            } else {
                std::cmp::Ordering::Equal
            })
        });
        if let Some(mesh) = scene.filter(|m| m.triangle_count() > 0) {
            let base = g.vertices.len() as u32;
            for (k, p) in mesh.positions.iter().enumerate() {
                g.vertices.push(Vertex {
                    position: *p,
                    receives_shadow: 1.0,
                    normal: mesh.normals.get(k).copied().unwrap_or([0.0, 0.0, 1.0]),
                    tangent: mesh.tangents.get(k).copied().unwrap_or([0.0; 4]),
                    uv0: mesh.uvs.get(k).copied().unwrap_or([0.0; 2]),
                    uv1: [0.0; 2],
                    color: [1.0; 4],
                });
            }
            let first = g.indices.len() as u32;
            let count = mesh.positions.len() as u32;
            g.indices.extend(
                mesh.indices
                    .chunks_exact(3)
                    .filter(|t| t.iter().all(|&i| i < count))
                    .flatten()
                    .map(|&i| base + i),
            );
            g.scene_range = Some((first, g.indices.len() as u32 - first));
            let pts: Vec<Vec3> = mesh.positions.iter().map(|p| Vec3::from(*p)).collect();
            g.scene_bounds = Aabb::from_points(&pts);
        }
        g
    }

    /// Bounds of everything drawn.
    pub fn all_bounds(&self) -> Option<Aabb> {
        match (self.artefact_bounds, self.scene_bounds) {
            (Some(a), Some(b)) => Some(a.union(&b)),
            (a, b) => a.or(b),
        }
    }
}

fn finite_or_zero(v: Vec3) -> Vec3 {
    if v.is_finite() {
        v
    } else {
        Vec3::ZERO
    }
}

/// The eight corners of a box.
pub(crate) fn corners(b: &Aabb) -> [Vec3; 8] {
    std::array::from_fn(|i| {
        Vec3::new(
            if i & 1 == 0 { b.min.x } else { b.max.x },
            if i & 2 == 0 { b.min.y } else { b.max.y },
            if i & 4 == 0 { b.min.z } else { b.max.z },
        )
    })
}
