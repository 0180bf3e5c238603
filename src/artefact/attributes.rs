//! Vertex normals and tangents when the file lacks them or gives unusable ones.

use glam::{Vec2, Vec3, Vec4};

/// Area-weighted vertex normals of a triangle list: each triangle adds its unnormalised cross
/// product (length = twice its area) to its three corners. Vertices touched by no
/// non-degenerate triangle get +Z, so the result is always finite and unit length.
pub(crate) fn area_weighted_normals(positions: &[Vec3], indices: &[u32]) -> Vec<Vec3> {
    let mut acc = vec![Vec3::ZERO; positions.len()];
    for t in indices.chunks_exact(3) {
        let [a, b, c] = [t[0] as usize, t[1] as usize, t[2] as usize];
        let n = (positions[b] - positions[a]).cross(positions[c] - positions[a]);
        if n.is_finite() {
            acc[a] += n;
            acc[b] += n;
            acc[c] += n;
        }
    }
    acc.into_iter().map(|n| n.normalize_or(Vec3::Z)).collect()
}

/// Replaces unusable normals: zero, non-finite or (nearly) zero length ones get the area-weighted
/// normal; merely non-unit ones are renormalised. Returns how many of each were fixed.
pub(crate) fn repair_normals(
    normals: &mut [Vec3],
    positions: &[Vec3],
    indices: &[u32],
) -> (usize, usize) {
    const DEGENERATE: f32 = 1e-6;
    const UNIT_TOLERANCE: f32 = 1e-3;
    let mut generated: Option<Vec<Vec3>> = None;
    let (mut replaced, mut renormalised) = (0, 0);
    for (i, n) in normals.iter_mut().enumerate() {
        let len = n.length();
        if !len.is_finite() || len < DEGENERATE {
            let g = generated.get_or_insert_with(|| area_weighted_normals(positions, indices));
            *n = g[i];
            replaced += 1;
        } else if (len - 1.0).abs() > UNIT_TOLERANCE {
            *n /= len;
            renormalised += 1;
        }
    }
    (replaced, renormalised)
}

/// Per-vertex tangents (xyz, handedness w = ±1) from per-triangle UV derivatives accumulated at
/// each corner, then Gram-Schmidt orthogonalised against the normal (the approach of Lengyel,
/// "Computing Tangent Space Basis Vectors for an Arbitrary Mesh", 2001, which MikkTSpace refines).
/// Where UVs are degenerate the tangent is any unit vector perpendicular to the normal.
pub(crate) fn generate_tangents(
    positions: &[Vec3],
    normals: &[Vec3],
    uvs: &[Vec2],
    indices: &[u32],
) -> Vec<Vec4> {
    let mut tan = vec![Vec3::ZERO; positions.len()];
    let mut bitan = vec![Vec3::ZERO; positions.len()];
    for t in indices.chunks_exact(3) {
        let [a, b, c] = [t[0] as usize, t[1] as usize, t[2] as usize];
        let e1 = positions[b] - positions[a];
        let e2 = positions[c] - positions[a];
        let d1 = uvs[b] - uvs[a];
        let d2 = uvs[c] - uvs[a];
        let det = d1.x * d2.y - d2.x * d1.y;
        if det.abs() < 1e-12 || !det.is_finite() {
            continue;
        }
        let r = 1.0 / det;
        let sdir = (e1 * d2.y - e2 * d1.y) * r;
        let tdir = (e2 * d1.x - e1 * d2.x) * r;
        if !(sdir.is_finite() && tdir.is_finite()) {
            continue;
        }
        for v in [a, b, c] {
            tan[v] += sdir;
            bitan[v] += tdir;
        }
    }
    (0..positions.len())
        .map(|i| {
            let n = normals[i];
            let t = (tan[i] - n * n.dot(tan[i])).normalize_or_zero();
            let t = if t == Vec3::ZERO {
                n.any_orthonormal_vector()
            } else {
                t
            };
            let w = if n.cross(t).dot(bitan[i]) < 0.0 {
                -1.0
            } else {
                1.0
            };
            t.extend(w)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit quad in the z = 0 plane split into two triangles, CCW seen from +Z.
    fn quad() -> (Vec<Vec3>, Vec<u32>) {
        (
            vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
            ],
            vec![0, 1, 2, 0, 2, 3],
        )
    }

    #[test]
    fn normals_of_a_ccw_quad_point_along_plus_z() {
        let (p, i) = quad();
        for n in area_weighted_normals(&p, &i) {
            assert!((n - Vec3::Z).length() < 1e-6, "{n}");
        }
    }

    #[test]
    fn area_weighting_favours_the_large_face() {
        // Vertex 0 is shared by a big triangle facing +Z and a tiny one facing +X.
        let p = vec![
            Vec3::ZERO,
            Vec3::new(10.0, 0.0, 0.0),
            Vec3::new(0.0, 10.0, 0.0),
            Vec3::new(0.0, 0.1, 0.0),
            Vec3::new(0.0, 0.0, 0.1),
        ];
        let n = area_weighted_normals(&p, &[0, 1, 2, 0, 3, 4]);
        // Expected: normalize((0,0,100) + (0.01,0,0)).
        let expected = Vec3::new(0.01, 0.0, 100.0).normalize();
        assert!((n[0] - expected).length() < 1e-6);
    }

    #[test]
    fn degenerate_geometry_still_gives_unit_normals() {
        let p = vec![Vec3::ONE; 3];
        let n = area_weighted_normals(&p, &[0, 1, 2]);
        assert!(n.iter().all(|n| (n.length() - 1.0).abs() < 1e-6));
    }

    #[test]
    fn repair_replaces_zero_and_renormalises_short_normals() {
        let (p, i) = quad();
        let mut n = vec![Vec3::ZERO, Vec3::new(0.0, 0.0, 0.1), Vec3::NAN, Vec3::Z];
        let (replaced, renormalised) = repair_normals(&mut n, &p, &i);
        assert_eq!((replaced, renormalised), (2, 1));
        for v in n {
            assert!((v - Vec3::Z).length() < 1e-6, "{v}");
        }
    }

    #[test]
    fn tangents_follow_increasing_u_and_handedness_follows_v() {
        let (p, i) = quad();
        let normals = vec![Vec3::Z; 4];
        let uv = vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.0, 1.0),
        ];
        for t in generate_tangents(&p, &normals, &uv, &i) {
            assert!((t.truncate() - Vec3::X).length() < 1e-6, "{t}");
            assert_eq!(t.w, 1.0);
        }
        // Mirrored v: the bitangent flips, so w flips.
        let flipped: Vec<Vec2> = uv.iter().map(|u| Vec2::new(u.x, 1.0 - u.y)).collect();
        for t in generate_tangents(&p, &normals, &flipped, &i) {
            assert!((t.truncate() - Vec3::X).length() < 1e-6, "{t}");
            assert_eq!(t.w, -1.0);
        }
        // Degenerate UVs: still unit and perpendicular to the normal.
        for t in generate_tangents(&p, &normals, &[Vec2::ZERO; 4], &i) {
            assert!((t.truncate().length() - 1.0).abs() < 1e-6);
            assert!(t.truncate().dot(Vec3::Z).abs() < 1e-6);
        }
    }
}
