//! Artefacts built in code: a unit cube and a unit sphere with one material (tests, and the
//! comparison with the reference renderer's built-in shapes).

use std::sync::Arc;

use glam::{Vec2, Vec3};

use crate::artefact::{Aabb, Artefact, Material, Primitive};

/// An artefact of one primitive with planar (x, z) texture coordinates.
pub(crate) fn artefact(
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    indices: Vec<u32>,
    material: Material,
) -> Arc<Artefact> {
    let bounds = Aabb::from_points(&positions).unwrap();
    let uv0 = Some(positions.iter().map(|p| Vec2::new(p.x, p.z)).collect());
    Arc::new(Artefact {
        source: "test".into(),
        primitives: vec![Primitive {
            mesh: 0,
            mesh_name: None,
            node: 0,
            primitive: 0,
            positions,
            normals,
            tangents: None,
            uv0,
            uv1: None,
            colors: None,
            indices,
            material: 0,
            bounds,
        }],
        materials: vec![material],
        textures: Vec::new(),
        extensions_used: Vec::new(),
        extensions_required: Vec::new(),
        warnings: Vec::new(),
        bounds,
    })
}

/// A unit cube centred at the origin (faces with their own normals, CCW outside).
pub(crate) fn cube(material: Material) -> Arc<Artefact> {
    let mut p = Vec::new();
    let mut n = Vec::new();
    let mut idx = Vec::new();
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let mut normal = Vec3::ZERO;
            normal[axis] = sign;
            let u = Vec3::from_array(std::array::from_fn(|k| {
                if k == (axis + 1) % 3 {
                    1.0
                } else {
                    0.0
                }
            }));
            let v = normal.cross(u);
            let base = p.len() as u32;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                p.push(0.5 * (normal + u * a + v * b));
                n.push(normal);
            }
            idx.extend_from_slice(&[base, base + 1, base + 2, base, base + 2, base + 3]);
        }
    }
    artefact(p, n, idx, material)
}

/// A UV sphere of radius 1 at the origin.
pub(crate) fn sphere(material: Material) -> Arc<Artefact> {
    let (rings, segs) = (48, 96);
    let mut p = Vec::new();
    for j in 0..=rings {
        let theta = std::f32::consts::PI * j as f32 / rings as f32;
        for i in 0..=segs {
            let phi = 2.0 * std::f32::consts::PI * i as f32 / segs as f32;
            p.push(Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                -theta.sin() * phi.sin(),
            ));
        }
    }
    let mut idx = Vec::new();
    for j in 0..rings {
        for i in 0..segs {
            let a = (j * (segs + 1) + i) as u32;
            let b = a + 1;
            let c = a + (segs + 1) as u32;
            let d = c + 1;
            idx.extend_from_slice(&[a, c, b, b, c, d]);
        }
    }
    let n = p.clone();
    artefact(p, n, idx, material)
}
