//! Simplification of the scene mesh to a triangle budget by quadric edge collapse (Garland &
//! Heckbert 1997), as half-edge collapses: a vertex is merged into a neighbour and every kept
//! vertex stays an original depth sample, so its UV still maps exactly onto the photo.
//!
//! The error of a collapse is the sum of squared distances to the planes of the triangles it
//! replaces, measured *relative to depth* (each plane's quadric is weighted by `area / z⁴`, i.e.
//! by its image-space area with distances divided by depth) so that near and far parts of the
//! photo are simplified alike. Flat regions cost nothing and go first; creases and the mesh's
//! boundaries (holes and the cuts at depth discontinuities, held by extra perpendicular quadrics
//! and by only sliding along themselves) stay fine. Collapses that would flip a triangle (its
//! normal turning by more than 60°) or make the surface non-manifold are refused.

use std::collections::HashMap;

use glam::{DVec3, Vec3};

use super::SceneMesh;

/// A half-edge collapse: (cost as f32 bits, the vertex to remove, the one to keep). Non-negative
/// floats order like their bit patterns.
type Candidate = (u32, u32, u32);

/// Weight of the boundary-preserving quadrics relative to the surface ones.
const BOUNDARY_WEIGHT: f64 = 10.0;
/// Edge-length term of the cost, as a fraction of the squared edge length per unit weight: like
/// a distance error of 0.03 % of the edge, so it only decides between nearly equal costs.
const TIE_BREAK: f64 = 1e-7;
/// A vertex may gather at most this many neighbours (keeps triangles well shaped, and the work per
/// collapse bounded).
const MAX_VALENCE: usize = 16;
/// A collapse may turn a triangle's normal by at most this much (cos 60°).
const MIN_NORMAL_DOT: f64 = 0.5;

/// A symmetric 4×4 quadric, upper triangle row by row.
#[derive(Clone, Copy, Default)]
struct Quadric([f64; 10]);

impl Quadric {
    fn plane(n: DVec3, d: f64, w: f64) -> Quadric {
        let (a, b, c) = (n.x, n.y, n.z);
        Quadric(
            [
                a * a,
                a * b,
                a * c,
                a * d,
                b * b,
                b * c,
                b * d,
                c * c,
                c * d,
                d * d,
            ]
            .map(|v| v * w),
        )
    }
    fn add(&self, o: &Quadric) -> Quadric {
        let mut r = self.0;
        for (x, y) in r.iter_mut().zip(o.0) {
            *x += y;
        }
        Quadric(r)
    }
    /// Sum of the plane weights (the trace of the 3×3 part, normals being unit).
    fn weight(&self) -> f64 {
        self.0[0] + self.0[4] + self.0[7]
    }
    fn error(&self, p: DVec3) -> f64 {
        let q = &self.0;
        let (x, y, z) = (p.x, p.y, p.z);
        let e = q[0] * x * x
            + 2.0 * q[1] * x * y
            + 2.0 * q[2] * x * z
            + 2.0 * q[3] * x
            + q[4] * y * y
            + 2.0 * q[5] * y * z
            + 2.0 * q[6] * y
            + q[7] * z * z
            + 2.0 * q[8] * z
            + q[9];
        e.max(0.0)
    }
}

/// Simplifies `mesh` to at most `max_triangles` triangles (when its topology allows: collapses
/// that would fold or tear the surface are refused, so a mesh of many tiny disconnected pieces can
/// stay above the budget). Normals and tangents are recomputed; positions and UVs of the kept
/// vertices are unchanged.
pub fn simplify(mesh: &SceneMesh, max_triangles: usize) -> SceneMesh {
    let n = mesh.positions.len();
    let pos: Vec<DVec3> = mesh
        .positions
        .iter()
        .map(|p| Vec3::from(*p).as_dvec3())
        .collect();
    let mut tris: Vec<[u32; 3]> = mesh
        .indices
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]])
        .collect();
    let mut alive = vec![true; tris.len()];
    let mut live_count = tris.len();
    if live_count <= max_triangles {
        return mesh.clone();
    }

    let mut vertex_tris: Vec<Vec<u32>> = vec![Vec::new(); n];
    for (t, tri) in tris.iter().enumerate() {
        for &v in tri {
            vertex_tris[v as usize].push(t as u32);
        }
    }

    // Surface quadrics.
    let mut quadrics = vec![Quadric::default(); n];
    for tri in &tris {
        let [a, b, c] = tri.map(|v| pos[v as usize]);
        let cross = (b - a).cross(c - a);
        let area2 = cross.length();
        if !(area2 > 0.0 && area2.is_finite()) {
            continue;
        }
        let normal = cross / area2;
        let z = -(a.z + b.z + c.z) / 3.0;
        let w = 0.5 * area2 / (z * z * z * z);
        let q = Quadric::plane(normal, -normal.dot(a), w);
        for &v in tri {
            quadrics[v as usize] = quadrics[v as usize].add(&q);
        }
    }

    // Boundary edges: in exactly one triangle.
    let mut edge_use: HashMap<(u32, u32), (u32, u32)> = HashMap::new();
    for (t, tri) in tris.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            let e = edge_use
                .entry((a.min(b), a.max(b)))
                .or_insert((0, t as u32));
            e.0 += 1;
        }
    }
    let mut boundary = vec![false; n];
    for (&(a, b), &(count, t)) in &edge_use {
        if count != 1 {
            continue;
        }
        boundary[a as usize] = true;
        boundary[b as usize] = true;
        let [p0, p1, p2] = tris[t as usize].map(|v| pos[v as usize]);
        let face_n = (p1 - p0).cross(p2 - p0).normalize_or_zero();
        let (pa, pb) = (pos[a as usize], pos[b as usize]);
        let m = (pb - pa).cross(face_n);
        let len = m.length();
        if !(len > 0.0 && len.is_finite()) {
            continue;
        }
        let m = m / len;
        let z = -(pa.z + pb.z) / 2.0;
        let w = BOUNDARY_WEIGHT * (pb - pa).length_squared() / (z * z * z * z);
        let q = Quadric::plane(m, -m.dot(pa), w);
        quadrics[a as usize] = quadrics[a as usize].add(&q);
        quadrics[b as usize] = quadrics[b as usize].add(&q);
    }

    drop(edge_use);
    let mut removed = vec![false; n];
    let mut neighbours = Vec::new();
    let mut candidates: Vec<Candidate> = Vec::new();
    // Rounds: cost every live edge in both directions, sort, and collapse in cost order while no
    // vertex is touched twice in a round (a collapse locks the kept vertex and its neighbours,
    // whose costs it changed). A sort per round is far more cache-friendly than a priority
    // queue with millions of stale entries, and about ten rounds reach any budget.
    let mut limit_to_cheapest = true;
    while live_count > max_triangles {
        candidates.clear();
        for (t, tri) in tris.iter().enumerate() {
            if !alive[t] {
                continue;
            }
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                // Each interior edge is in two triangles: take it from the one where a < b, or
                // from its only triangle on the boundary.
                if a < b || boundary[a as usize] && boundary[b as usize] {
                    for (u, v) in [(a, b), (b, a)] {
                        let q = quadrics[u as usize].add(&quadrics[v as usize]);
                        // Ties (a flat region costs ~0 everywhere) go to the shorter edge, so
                        // flat regions coarsen evenly instead of growing fans.
                        let length2 = (pos[u as usize] - pos[v as usize]).length_squared();
                        let cost = q.error(pos[v as usize]) + TIE_BREAK * q.weight() * length2;
                        candidates.push(((cost as f32).to_bits(), u, v));
                    }
                }
            }
        }
        candidates.sort_unstable();
        let mut locked = vec![false; n];
        let before = live_count;
        // At most half of what is still to remove per round, so that late collapses are chosen
        // with up-to-date costs.
        let round_target = live_count - (live_count - max_triangles).div_ceil(2);
        // …and only among the cheapest candidates: each collapse removes about two triangles, so
        // the round may use the cheapest `2 × (triangles to remove)` edge directions — a flat
        // region locked by its neighbours' collapses waits for the next round rather than
        // letting a curved edge go first.
        let cheapest = (2 * (live_count - round_target)).min(candidates.len() - 1);
        let threshold = if limit_to_cheapest {
            candidates[cheapest].0
        } else {
            u32::MAX
        };
        for &(cost, u, v) in &candidates {
            if live_count <= round_target.max(max_triangles) || cost > threshold {
                break;
            }
            let (ui, vi) = (u as usize, v as usize);
            if removed[ui] || removed[vi] || locked[ui] || locked[vi] {
                continue;
            }
            let Some(shared) = collapse_allowed(u, v, &vertex_tris, &tris, &alive, &boundary, &pos)
            else {
                continue;
            };
            for &t in &shared {
                alive[t as usize] = false;
                live_count -= 1;
            }
            let moved: Vec<u32> = vertex_tris[ui]
                .iter()
                .copied()
                .filter(|&t| alive[t as usize])
                .collect();
            for &t in &moved {
                for w in tris[t as usize].iter_mut() {
                    if *w == u {
                        *w = v;
                    }
                }
            }
            removed[ui] = true;
            vertex_tris[ui] = Vec::new();
            let mut merged: Vec<u32> = vertex_tris[vi]
                .iter()
                .copied()
                .filter(|&t| alive[t as usize])
                .collect();
            merged.extend(moved);
            vertex_tris[vi] = merged;
            quadrics[vi] = quadrics[vi].add(&quadrics[ui]);
            locked[vi] = true;
            collect_neighbours(&vertex_tris[vi], &tris, &alive, v, &mut neighbours);
            for &w in &neighbours {
                locked[w as usize] = true;
            }
        }
        if live_count == before {
            if !limit_to_cheapest {
                // Every remaining collapse would fold or tear the surface.
                break;
            }
            // The cheapest ones were all refused: try the whole list once.
            limit_to_cheapest = false;
        } else {
            limit_to_cheapest = true;
        }
    }

    let mut out = SceneMesh {
        positions: mesh.positions.clone(),
        // Every kept vertex is an original sample: its normal (robust, from the full-resolution
        // depth) stays valid, and is better than one from the coarse triangles.
        normals: mesh.normals.clone(),
        tangents: Vec::new(),
        uvs: mesh.uvs.clone(),
        indices: tris
            .iter()
            .zip(&alive)
            .filter(|(_, a)| **a)
            .flat_map(|(t, _)| *t)
            .collect(),
    };
    out.remove_unused_vertices();
    out.recompute_tangents_keeping_normals();
    out
}

/// The triangles on edge `u`–`v` when collapsing `u` into `v` keeps the surface a manifold
/// without folds (link condition, boundary rule, valence cap, normal turn), else `None`.
fn collapse_allowed(
    u: u32,
    v: u32,
    vertex_tris: &[Vec<u32>],
    tris: &[[u32; 3]],
    alive: &[bool],
    boundary: &[bool],
    pos: &[DVec3],
) -> Option<Vec<u32>> {
    let (ui, vi) = (u as usize, v as usize);
    let mut neighbours_u = Vec::new();
    let mut neighbours_v = Vec::new();
    // Triangles on the edge, and the link condition (common neighbours = opposite corners).
    let shared: Vec<u32> = vertex_tris[ui]
        .iter()
        .copied()
        .filter(|&t| alive[t as usize] && tris[t as usize].contains(&v))
        .collect();
    if shared.is_empty() {
        return None;
    }
    if boundary[ui] && !(shared.len() == 1 && boundary[vi]) {
        return None;
    }
    collect_neighbours(&vertex_tris[ui], tris, alive, u, &mut neighbours_u);
    collect_neighbours(&vertex_tris[vi], tris, alive, v, &mut neighbours_v);
    let common = neighbours_u
        .iter()
        .filter(|w| neighbours_v.contains(w))
        .count();
    if common != shared.len() {
        return None;
    }
    if neighbours_u.len() + neighbours_v.len() - common - 2 > MAX_VALENCE {
        return None;
    }
    // No flipped or degenerate triangle.
    let folds = vertex_tris[ui].iter().any(|&t| {
        let tri = tris[t as usize];
        if !alive[t as usize] || tri.contains(&v) {
            return false;
        }
        let corners = tri.map(|w| pos[w as usize]);
        let moved = tri.map(|w| if w == u { pos[vi] } else { pos[w as usize] });
        let before = (corners[1] - corners[0]).cross(corners[2] - corners[0]);
        let after = (moved[1] - moved[0]).cross(moved[2] - moved[0]);
        let (lb, la) = (before.length(), after.length());
        !(la > 0.0 && la.is_finite()) || before.dot(after) < MIN_NORMAL_DOT * lb * la
    });
    if folds {
        return None;
    }

    Some(shared)
}

/// The distinct vertices sharing a live triangle with `v` (excluding `v`).
fn collect_neighbours(
    vertex_tris: &[u32],
    tris: &[[u32; 3]],
    alive: &[bool],
    v: u32,
    out: &mut Vec<u32>,
) {
    out.clear();
    for &t in vertex_tris {
        if !alive[t as usize] {
            continue;
        }
        for w in tris[t as usize] {
            if w != v && !out.contains(&w) {
                out.push(w);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Camera;
    use crate::image::Raster;
    use crate::mesh::MeshOptions;

    /// Largest distance (relative to depth) from the ray through each pixel centre to the mesh,
    /// measured against the analytic depth: checks the simplified mesh still is the scene.
    fn max_relative_depth_error(
        mesh: &SceneMesh,
        camera: &Camera,
        truth: &Raster<f32>,
    ) -> (f32, usize) {
        let bvh = crate::mesh::Bvh::new(mesh);
        let (mut worst, mut missed) = (0.0f32, 0);
        for y in 0..truth.height() {
            for x in 0..truth.width() {
                let z = *truth.get(x, y);
                let pixel = glam::Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                match crate::mesh::pick(&bvh, camera, pixel) {
                    Some(hit) => worst = worst.max(((-hit.point.z - z) / z).abs()),
                    None => missed += 1,
                }
            }
        }
        (worst, missed)
    }

    #[test]
    fn boxes_on_a_floor_keep_their_shape_at_a_small_budget() {
        let camera = Camera::from_focal(120.0, 96, 72).unwrap();
        // Back wall at 6 m, a box 1.5 m nearer on the right (a depth step), the left half a
        // slanted plane: three planar pieces the simplified mesh must keep exactly.
        let truth = Raster::from_fn(96, 72, |x, y| {
            let dir = camera.ray_direction(x as f32 + 0.5, y as f32 + 0.5);
            if x < 48 {
                let n = Vec3::new(0.4, 0.1, 1.0).normalize();
                -4.0 / n.dot(dir) * -dir.z
            } else if (60..84).contains(&x) && (20..50).contains(&y) {
                4.5
            } else {
                6.0
            }
        });
        let full = SceneMesh::from_depth(&truth, &camera, &MeshOptions::default()).unwrap();
        let budget = 200;
        let small = simplify(&full, budget);
        assert!(
            small.triangle_count() <= budget,
            "{}",
            small.triangle_count()
        );
        assert!(full.triangle_count() > 40 * budget);
        let (worst, missed) = max_relative_depth_error(&small, &camera, &truth);
        assert!(worst < 1e-3, "relative depth error {worst}");
        // Only pixels at the cut outline may fall through (their quads were cut in the grid too).
        let (_, missed_full) = max_relative_depth_error(&full, &camera, &truth);
        assert!(missed <= missed_full + 96, "{missed} vs {missed_full}");
        for n in &small.normals {
            assert!((Vec3::from(*n).length() - 1.0).abs() < 1e-4);
        }
        assert!(small
            .indices
            .iter()
            .all(|&i| (i as usize) < small.positions.len()));
    }

    #[test]
    fn curved_surface_keeps_more_triangles_where_it_bends() {
        // A cylinder-like bump across the left half, flat on the right: the flat half must end
        // with far fewer triangles than the curved half.
        let camera = Camera::from_focal(100.0, 80, 40).unwrap();
        let truth = Raster::from_fn(80, 40, |x, _| {
            if x < 40 {
                3.0 - 0.3 * ((x as f32) / 40.0 * std::f32::consts::PI).sin()
            } else {
                3.0
            }
        });
        let full = SceneMesh::from_depth(&truth, &camera, &MeshOptions::default()).unwrap();
        let small = simplify(&full, 300);
        let (mut left, mut right) = (0, 0);
        for t in 0..small.triangle_count() {
            let c = small.triangle(t).iter().map(|p| p.x).sum::<f32>() / 3.0;
            if c < -0.1 {
                left += 1;
            } else if c > 0.1 {
                right += 1;
            }
        }
        assert!(left > 3 * right, "curved {left} vs flat {right}");
    }
}
