//! Procedural shapes turned into triangles (object space, counter-clockwise = outside).

use glam::Vec3;
use std::f32::consts::{PI, TAU};

use super::description::Shape;

const DEFAULT_SEGMENTS: u32 = 48;

/// An indexed triangle mesh with one normal per vertex.
#[derive(Debug, Clone, Default)]
pub(crate) struct TriMesh {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub indices: Vec<[u32; 3]>,
}

impl TriMesh {
    fn vertex(&mut self, p: Vec3, n: Vec3) -> u32 {
        self.positions.push(p);
        self.normals.push(n);
        self.positions.len() as u32 - 1
    }

    /// A flat quad `a b c d` (counter-clockwise seen from the side `n` points to).
    fn quad(&mut self, a: Vec3, b: Vec3, c: Vec3, d: Vec3, n: Vec3) {
        let i = [a, b, c, d].map(|p| self.vertex(p, n));
        self.indices.push([i[0], i[1], i[2]]);
        self.indices.push([i[0], i[2], i[3]]);
    }

    /// A grid of `(nu + 1) × (nv + 1)` vertices from `f(u, v) -> (position, normal)`, u and v in
    /// [0, 1], triangulated counter-clockwise when `∂p/∂u × ∂p/∂v` points outwards.
    fn grid(&mut self, nu: u32, nv: u32, f: impl Fn(f32, f32) -> (Vec3, Vec3)) {
        let base = self.positions.len() as u32;
        for j in 0..=nv {
            for i in 0..=nu {
                let (p, n) = f(i as f32 / nu as f32, j as f32 / nv as f32);
                self.vertex(p, n);
            }
        }
        let row = nu + 1;
        for j in 0..nv {
            for i in 0..nu {
                let a = base + j * row + i;
                let b = a + 1;
                let c = a + row + 1;
                let d = a + row;
                self.indices.push([a, b, c]);
                self.indices.push([a, c, d]);
            }
        }
    }
}

/// Tessellates a shape. Degenerate triangles (the poles of a sphere) are dropped.
pub(crate) fn tessellate(shape: &Shape) -> TriMesh {
    let mut m = TriMesh::default();
    match shape {
        Shape::Plane { size } => {
            let (x, z) = (size[0] / 2.0, size[1] / 2.0);
            m.quad(
                Vec3::new(-x, 0.0, z),
                Vec3::new(x, 0.0, z),
                Vec3::new(x, 0.0, -z),
                Vec3::new(-x, 0.0, -z),
                Vec3::Y,
            );
        }
        Shape::Box { size } => {
            let h = Vec3::from(*size) / 2.0;
            for axis in 0..3 {
                for sign in [-1.0f32, 1.0] {
                    let mut n = Vec3::ZERO;
                    n[axis] = sign;
                    // Two tangents so that t × b = n.
                    let t = [Vec3::Y, Vec3::Z, Vec3::X][axis] * sign;
                    let b = n.cross(t);
                    let (t, b) = (t * h, b * h);
                    let c = n * h;
                    m.quad(c - t - b, c + t - b, c + t + b, c - t + b, n);
                }
            }
        }
        Shape::Sphere { radius, segments } => {
            let s = segments.unwrap_or(DEFAULT_SEGMENTS);
            let r = *radius;
            m.grid(s, (s / 2).max(2), |u, v| {
                let theta = v * PI;
                let phi = u * TAU;
                // Exact poles: sin(π) is not 0 in f32, which would leave slivers there.
                let (sin_t, cos_t) = match v {
                    0.0 => (0.0, 1.0),
                    1.0 => (0.0, -1.0),
                    _ => theta.sin_cos(),
                };
                let n = Vec3::new(sin_t * phi.cos(), cos_t, sin_t * phi.sin());
                (n * r, n)
            });
        }
        Shape::Cylinder {
            radius,
            height,
            segments,
        } => {
            let s = segments.unwrap_or(DEFAULT_SEGMENTS);
            let (r, h) = (*radius, *height / 2.0);
            m.grid(s, 1, |u, v| {
                let phi = u * TAU;
                let n = Vec3::new(phi.cos(), 0.0, phi.sin());
                (n * r + Vec3::Y * (h - 2.0 * h * v), n)
            });
            for (y, n) in [(h, Vec3::Y), (-h, -Vec3::Y)] {
                let centre = m.vertex(Vec3::new(0.0, y, 0.0), n);
                let ring: Vec<u32> = (0..s)
                    .map(|i| {
                        let phi = i as f32 / s as f32 * TAU;
                        m.vertex(Vec3::new(r * phi.cos(), y, r * phi.sin()), n)
                    })
                    .collect();
                for i in 0..s as usize {
                    let (a, b) = (ring[i], ring[(i + 1) % s as usize]);
                    // Counter-clockwise seen from outside the cap.
                    if n.y > 0.0 {
                        m.indices.push([centre, b, a]);
                    } else {
                        m.indices.push([centre, a, b]);
                    }
                }
            }
        }
        Shape::Torus {
            major_radius,
            minor_radius,
            segments,
        } => {
            let s = segments.unwrap_or(DEFAULT_SEGMENTS);
            let (big, small) = (*major_radius, *minor_radius);
            m.grid(s, (s / 2).max(3), |u, v| {
                let phi = -u * TAU;
                let theta = v * TAU;
                let ring = Vec3::new(phi.cos(), 0.0, phi.sin());
                let n = ring * theta.cos() + Vec3::Y * theta.sin();
                (ring * big + n * small, n)
            });
        }
        Shape::Mesh {
            positions,
            indices,
            normals,
        } => {
            let positions: Vec<Vec3> = positions.iter().map(|p| Vec3::from(*p)).collect();
            match normals {
                Some(n) => {
                    m.positions = positions;
                    m.normals = n
                        .iter()
                        .map(|v| Vec3::from(*v).normalize_or_zero())
                        .collect();
                    m.indices = indices.clone();
                }
                None => {
                    for tri in indices {
                        let [a, b, c] = tri.map(|i| positions[i as usize]);
                        let n = (b - a).cross(c - a).normalize_or_zero();
                        let i = [a, b, c].map(|p| m.vertex(p, n));
                        m.indices.push(i);
                    }
                }
            }
        }
    }
    let positions = &m.positions;
    m.indices.retain(|t| {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        (b - a).cross(c - a).length_squared() > 0.0
    });
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Closed, outward-facing meshes have a positive signed volume equal to the solid's.
    fn signed_volume(m: &TriMesh) -> f32 {
        m.indices
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| m.positions[i as usize]);
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    #[test]
    fn closed_shapes_enclose_their_volume_facing_outwards() {
        let cases = [
            (
                Shape::Box {
                    size: [1.0, 2.0, 3.0],
                },
                6.0,
                1e-5,
            ),
            (
                Shape::Sphere {
                    radius: 0.5,
                    segments: Some(256),
                },
                4.0 / 3.0 * PI * 0.125,
                2e-3,
            ),
            (
                Shape::Cylinder {
                    radius: 0.5,
                    height: 2.0,
                    segments: Some(256),
                },
                PI * 0.25 * 2.0,
                2e-3,
            ),
            (
                Shape::Torus {
                    major_radius: 1.0,
                    minor_radius: 0.25,
                    segments: Some(256),
                },
                2.0 * PI * PI * 1.0 * 0.0625,
                2e-3,
            ),
        ];
        for (shape, volume, tol) in cases {
            let v = signed_volume(&tessellate(&shape));
            assert!(
                (v / volume - 1.0).abs() < tol,
                "{shape:?}: volume {v}, expected {volume}"
            );
        }
    }

    #[test]
    fn normals_agree_with_winding() {
        for shape in [
            Shape::Plane { size: [2.0, 1.0] },
            Shape::Box { size: [1.0; 3] },
            Shape::Sphere {
                radius: 1.0,
                segments: None,
            },
            Shape::Cylinder {
                radius: 1.0,
                height: 1.0,
                segments: None,
            },
        ] {
            let m = tessellate(&shape);
            for t in &m.indices {
                let [a, b, c] = t.map(|i| m.positions[i as usize]);
                let face = (b - a).cross(c - a);
                let n = m.normals[t[0] as usize];
                assert!(face.dot(n) > 0.0, "{shape:?}: face against its normal");
            }
        }
    }
}
