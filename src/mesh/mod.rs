//! The scene mesh: the photo's 3D counterpart (thesis §3.2.2–3.2.3, Algorithm 4 improved) and what
//! is built on it — ray queries, support surfaces, placement and export.
//!
//! | file | job |
//! |---|---|
//! | [`grid`] | depth map → [`SceneMesh`]: one vertex per pixel (or block), cut at depth discontinuities |
//! | `local_fit` | normals robust to depth noise: edge-aware plane fits in inverse depth, growing with the noise |
//! | [`simplify`] | quadric edge collapse down to a triangle budget: flat regions coarse, edges fine |
//! | [`bvh`] | [`Bvh`]: closest-hit (pick) and any-hit (occlusion) queries over obvhs' CWBVH |
//! | [`surfaces`] | support planes (RANSAC + refinement) and the gravity "up" |
//! | [`place`](mod@place) | transforms that stand an object on the surface under a pixel or a ray |
//! | [`export`] | depth (PFM, 16-bit PNG mm), PLY, OBJ, GLB with the photo as texture |
//! | `filled` | which pixels of the depth were filled, not measured, from its confidence |

pub mod bvh;
pub mod export;
mod filled;
pub mod grid;
pub(crate) mod local_fit;
pub mod place;
pub mod simplify;
pub mod surfaces;

pub use bvh::{pick, Bvh, Hit, Ray};
pub use grid::MeshOptions;
pub use place::{
    place, place_on_ray, Orientation, PlaceOptions, Placement, PlacementScene,
    PLACE_SEARCH_RADIUS_PX,
};
pub use surfaces::{
    detect_surfaces, detect_surfaces_with_confidence, detect_surfaces_with_host_up, SupportSurface,
    SurfaceKind, SurfaceOptions, Surfaces, UpSource,
};

use glam::{DVec3, Vec3};
use rayon::prelude::*;

/// A triangle mesh of the photographed scene in the camera (= world) frame, metres.
///
/// Triangles are counter-clockwise seen from the camera, so their front faces and the normals point
/// towards it. Every attribute vector has one entry per vertex; `indices` holds three vertex
/// indices per triangle, each `< positions.len()`. No value is NaN or infinite, every normal has
/// unit length, and every tangent is a unit vector perpendicular to its normal with the bitangent
/// sign (±1) in `w` (glTF: `bitangent = cross(normal, tangent.xyz) · w`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SceneMesh {
    /// Vertex positions, metres.
    pub positions: Vec<[f32; 3]>,
    /// Unit vertex normals, facing the camera. From [`SceneMesh::from_depth`]: the normal of a
    /// plane fitted robustly to the depth around the vertex (see [`grid`]), and in a
    /// [`Scene`](crate::scene::Scene)'s mesh, on a detected support surface, that surface's normal
    /// ([`Surfaces::snap_mesh_normals`]); otherwise smooth, area-weighted over the triangles that
    /// share the vertex.
    pub normals: Vec<[f32; 3]>,
    /// Unit tangents along increasing `u` of the photo, with the bitangent sign in `w`.
    pub tangents: Vec<[f32; 4]>,
    /// Texture coordinates into the photo: (0, 0) its top-left corner, (1, 1) its bottom-right
    /// (glTF convention).
    pub uvs: Vec<[f32; 2]>,
    /// Three vertex indices per triangle.
    pub indices: Vec<u32>,
}

impl SceneMesh {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// The three corner positions of triangle `t`.
    ///
    /// # Panics
    /// When `t` is out of range.
    pub fn triangle(&self, t: usize) -> [Vec3; 3] {
        let i = &self.indices[3 * t..3 * t + 3];
        [0, 1, 2].map(|k| Vec3::from(self.positions[i[k] as usize]))
    }

    /// Recomputes smooth normals and tangents from positions, UVs and indices (after positions
    /// changed, e.g. by simplification).
    pub fn recompute_normals_and_tangents(&mut self) {
        let (normals, tangents) =
            normals_and_tangents(&self.positions, &self.uvs, &self.indices, None);
        self.normals = normals;
        self.tangents = tangents;
    }

    /// Recomputes the tangents for the current normals, keeping each normal that is finite and of
    /// unit length (e.g. the robust normals of [`SceneMesh::from_depth`], which a simplification
    /// keeps for the samples it keeps) and recomputing the others from the triangles.
    pub fn recompute_tangents_keeping_normals(&mut self) {
        let given = std::mem::take(&mut self.normals);
        let given = (given.len() == self.positions.len()).then_some(given.as_slice());
        let (normals, tangents) =
            normals_and_tangents(&self.positions, &self.uvs, &self.indices, given);
        self.normals = normals;
        self.tangents = tangents;
    }

    /// Removes vertices that no triangle uses, keeping the order of the others.
    pub fn remove_unused_vertices(&mut self) {
        let mut remap = vec![u32::MAX; self.positions.len()];
        for &i in &self.indices {
            remap[i as usize] = 0;
        }
        let mut next = 0u32;
        for r in remap.iter_mut() {
            if *r == 0 {
                *r = next;
                next += 1;
            }
        }
        let keep = |v: usize| remap[v] != u32::MAX;
        fn compact<T: Copy>(values: &[T], keep: impl Fn(usize) -> bool) -> Vec<T> {
            values
                .iter()
                .enumerate()
                .filter(|(i, _)| keep(*i))
                .map(|(_, v)| *v)
                .collect()
        }
        self.positions = compact(&self.positions, keep);
        if self.normals.len() == remap.len() {
            self.normals = compact(&self.normals, keep);
        }
        if self.tangents.len() == remap.len() {
            self.tangents = compact(&self.tangents, keep);
        }
        if self.uvs.len() == remap.len() {
            self.uvs = compact(&self.uvs, keep);
        }
        for i in self.indices.iter_mut() {
            *i = remap[*i as usize];
        }
    }
}

/// Area-weighted smooth normals (or the `given` ones where those are finite and unit) and
/// UV-aligned tangents. A vertex whose triangles cancel out (or that no triangle uses) gets the
/// direction towards the camera, so no normal is ever degenerate.
pub(crate) fn normals_and_tangents(
    positions: &[[f32; 3]],
    uvs: &[[f32; 2]],
    indices: &[u32],
    given: Option<&[[f32; 3]]>,
) -> (Vec<[f32; 3]>, Vec<[f32; 4]>) {
    let n = positions.len();
    let mut normal_sum = vec![DVec3::ZERO; n];
    let mut tangent_sum = vec![DVec3::ZERO; n];
    let mut bitangent_sum = vec![DVec3::ZERO; n];
    // Each block's triangle terms are computed in parallel, then summed in triangle order, so
    // the sums (and the result) are those of a serial pass, bit for bit; blocks bound the memory
    // the terms take.
    const BLOCK_TRIANGLES: usize = 1 << 16;
    let mut terms = Vec::with_capacity(BLOCK_TRIANGLES.min(indices.len() / 3));
    for block in indices.chunks(3 * BLOCK_TRIANGLES) {
        block
            .par_chunks_exact(3)
            .map(|tri| triangle_terms(positions, uvs, [tri[0], tri[1], tri[2]]))
            .collect_into_vec(&mut terms);
        for (tri, terms) in block.chunks_exact(3).zip(&terms) {
            let Some(t) = terms else {
                continue;
            };
            for &i in tri {
                let i = i as usize;
                normal_sum[i] += t.weighted;
                tangent_sum[i] += t.tangent;
                bitangent_sum[i] += t.bitangent;
            }
        }
    }
    (0..n)
        .into_par_iter()
        .map(|i| {
            let towards_camera = (-Vec3::from(positions[i]).as_dvec3()).normalize_or(DVec3::Z);
            let kept = given
                .map(|g| Vec3::from(g[i]).as_dvec3())
                .filter(|g| g.is_finite() && (g.length() - 1.0).abs() < 1e-3)
                .map(|g| g.normalize());
            let normal = kept
                .or_else(|| normal_sum[i].try_normalize())
                .unwrap_or(towards_camera);
            // Gram–Schmidt; fall back to any perpendicular when UVs say nothing.
            let t = tangent_sum[i] - normal * normal.dot(tangent_sum[i]);
            let tangent = t
                .try_normalize()
                .unwrap_or_else(|| normal.any_orthonormal_vector());
            let w = if normal.cross(tangent).dot(bitangent_sum[i]) < 0.0 {
                -1.0
            } else {
                1.0
            };
            (
                normal.as_vec3().to_array(),
                tangent.as_vec3().extend(w as f32).to_array(),
            )
        })
        .unzip()
}

/// What one triangle adds to each of its vertices in [`normals_and_tangents`].
struct TriangleTerms {
    /// Its normal weighted by area, scale-free.
    weighted: DVec3,
    /// Its UV-aligned tangent and bitangent, weighted by the same area.
    tangent: DVec3,
    bitangent: DVec3,
}

/// The terms of the triangle `[i0, i1, i2]`; `None` when it is degenerate (no area).
fn triangle_terms(
    positions: &[[f32; 3]],
    uvs: &[[f32; 2]],
    tri: [u32; 3],
) -> Option<TriangleTerms> {
    let [i0, i1, i2] = tri.map(|i| i as usize);
    let p0 = Vec3::from(positions[i0]).as_dvec3();
    let e1 = Vec3::from(positions[i1]).as_dvec3() - p0;
    let e2 = Vec3::from(positions[i2]).as_dvec3() - p0;
    let cross = e1.cross(e2);
    let len = cross.length();
    if !(len.is_finite() && len > 0.0) {
        return None;
    }
    // Weight by area, but in a scale-free way: normalise by the triangle's longest edge² so
    // that f64 sums stay finite for any metric scale.
    let scale = e1.length_squared().max(e2.length_squared());
    let weighted = cross / scale;
    // Tangent frame from UV gradients (Lengyel).
    let (t, b) = if uvs.len() == positions.len() {
        let uv0 = glam::Vec2::from(uvs[i0]).as_dvec2();
        let d1 = glam::Vec2::from(uvs[i1]).as_dvec2() - uv0;
        let d2 = glam::Vec2::from(uvs[i2]).as_dvec2() - uv0;
        let det = d1.x * d2.y - d2.x * d1.y;
        if det.abs() > 1e-300 {
            let r = 1.0 / det;
            (
                ((e1 * d2.y - e2 * d1.y) * r).normalize_or_zero(),
                ((e2 * d1.x - e1 * d2.x) * r).normalize_or_zero(),
            )
        } else {
            (DVec3::ZERO, DVec3::ZERO)
        }
    } else {
        (DVec3::ZERO, DVec3::ZERO)
    };
    let area_weight = weighted.length();
    Some(TriangleTerms {
        weighted,
        tangent: t * area_weight,
        bitangent: b * area_weight,
    })
}
