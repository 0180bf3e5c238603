//! The node hierarchy flattened into world transforms, and mesh primitives turned into indexed
//! triangle lists in that flattened space.

use glam::{Mat3, Mat4, Quat, Vec2, Vec3, Vec4};
use gltf::accessor::Dimensions;
use gltf::mesh::{Mode, Semantic};

use super::attributes;
use super::buffers::{read_floats, read_indices, Buffers};
use super::limits::{mul, LoadLimits, MemoryBudget};
use super::{Aabb, Primitive};
use crate::error::{Error, Result};

/// A node that carries a mesh, with its world transform.
pub(crate) struct MeshInstance<'a> {
    pub(crate) node: gltf::Node<'a>,
    pub(crate) mesh: gltf::Mesh<'a>,
    pub(crate) world: Mat4,
}

fn node_label(node: &gltf::Node) -> String {
    match node.name() {
        Some(n) => format!("node {} ('{n}')", node.index()),
        None => format!("node {}", node.index()),
    }
}

/// The nodes to draw: the default scene's, else the first scene's, else every node that is no
/// other node's child (with a warning).
///
/// # Errors
/// `Format` for a cycle (named node by node), a node reached twice (two parents), or a
/// non-finite transform; `TooLarge` past [`LoadLimits::max_nodes`].
pub(crate) fn flatten<'a>(
    doc: &'a gltf::Document,
    limits: &LoadLimits,
    warnings: &mut Vec<String>,
) -> Result<Vec<MeshInstance<'a>>> {
    let nodes: Vec<gltf::Node<'a>> = doc.nodes().collect();
    let roots: Vec<usize> = if let Some(scene) = doc.default_scene().or_else(|| doc.scenes().next())
    {
        scene.nodes().map(|n| n.index()).collect()
    } else {
        let mut is_child = vec![false; nodes.len()];
        for node in &nodes {
            for child in node.children() {
                is_child[child.index()] = true;
            }
        }
        let roots: Vec<usize> = (0..nodes.len()).filter(|&i| !is_child[i]).collect();
        if !nodes.is_empty() {
            warnings.push(format!(
                "the asset has no scene; drawing its {} root node(s)",
                roots.len()
            ));
        }
        roots
    };

    enum Step {
        Enter(usize, Mat4),
        Leave,
    }
    #[derive(Clone, Copy, PartialEq)]
    enum State {
        New,
        OnPath,
        Done,
    }
    let mut state = vec![State::New; nodes.len()];
    // The chain of nodes from the root to the one being visited, to name a cycle.
    let mut path: Vec<usize> = Vec::new();
    let mut visits: u64 = 0;
    let mut out = Vec::new();
    // An explicit stack: a deep (or hostile) hierarchy must not overflow the thread's stack.
    let mut stack: Vec<Step> = roots
        .iter()
        .rev()
        .map(|&r| Step::Enter(r, Mat4::IDENTITY))
        .collect();
    while let Some(step) = stack.pop() {
        let (index, parent_world) = match step {
            Step::Leave => {
                if let Some(i) = path.pop() {
                    state[i] = State::Done;
                }
                continue;
            }
            Step::Enter(i, w) => (i, w),
        };
        match state[index] {
            State::New => {}
            State::OnPath => {
                let start = path.iter().position(|&n| n == index).unwrap_or(0);
                let mut cycle: Vec<String> = path[start..].iter().map(|n| n.to_string()).collect();
                cycle.push(index.to_string());
                return Err(Error::format(format!("node cycle: {}", cycle.join(" → "))));
            }
            State::Done => {
                return Err(Error::format(format!(
                    "node {index} is reached twice{}; glTF node hierarchies must be trees",
                    match path.last() {
                        Some(p) => format!(" (again as a child of node {p})"),
                        None => " (listed twice as a scene root, or a root that is also a child)"
                            .to_string(),
                    }
                )));
            }
        }
        state[index] = State::OnPath;
        path.push(index);
        stack.push(Step::Leave);
        visits += 1;
        if visits > limits.max_nodes {
            return Err(Error::TooLarge(format!(
                "the scene has more than {} nodes (LoadLimits::max_nodes)",
                limits.max_nodes
            )));
        }
        let node = &nodes[index];
        let world = parent_world * local_matrix(node, warnings)?;
        if !world.is_finite() {
            return Err(Error::format(format!(
                "{}: its world transform overflows (non-finite)",
                node_label(node)
            )));
        }
        if let Some(mesh) = node.mesh() {
            if node.skin().is_some() {
                warnings.push(format!(
                    "{}: skinning is not applied; the mesh is drawn in its bind pose",
                    node_label(node)
                ));
            }
            let weights = node.weights().or(mesh.weights()).unwrap_or(&[]);
            if weights.iter().any(|&w| w != 0.0) {
                warnings.push(format!(
                    "{}: morph target weights are not applied; the base mesh is drawn",
                    node_label(node)
                ));
            }
            out.push(MeshInstance {
                node: node.clone(),
                mesh,
                world,
            });
        }
        let children: Vec<usize> = node.children().map(|c| c.index()).collect();
        for &c in children.iter().rev() {
            stack.push(Step::Enter(c, world));
        }
    }
    Ok(out)
}

/// The node's local transform (matrix, or translation · rotation · scale).
fn local_matrix(node: &gltf::Node, warnings: &mut Vec<String>) -> Result<Mat4> {
    match node.transform() {
        gltf::scene::Transform::Matrix { matrix } => {
            let m = Mat4::from_cols_array_2d(&matrix);
            if !m.is_finite() {
                return Err(Error::format(format!(
                    "{}: matrix has a non-finite element",
                    node_label(node)
                )));
            }
            Ok(m)
        }
        gltf::scene::Transform::Decomposed {
            translation,
            rotation,
            scale,
        } => {
            let t = Vec3::from(translation);
            let q = Quat::from_array(rotation);
            let s = Vec3::from(scale);
            if !(t.is_finite() && q.is_finite() && s.is_finite()) {
                return Err(Error::format(format!(
                    "{}: translation, rotation or scale has a non-finite element",
                    node_label(node)
                )));
            }
            let len = q.length();
            if len < 1e-6 {
                return Err(Error::format(format!(
                    "{}: rotation quaternion {rotation:?} has zero length",
                    node_label(node)
                )));
            }
            if (len - 1.0).abs() > 1e-3 {
                warnings.push(format!(
                    "{}: rotation quaternion has length {len}; normalised",
                    node_label(node)
                ));
            }
            Ok(Mat4::from_scale_rotation_translation(s, q / len, t))
        }
    }
}

/// Vertex and triangle counts a primitive claims (from accessor counts, before reading data).
pub(crate) struct Claim {
    pub(crate) vertices: u64,
    pub(crate) triangles: u64,
}

/// What a primitive will cost, or `None` (with a warning) when it draws no triangles.
///
/// # Errors
/// `Format` when a triangle list's index (or vertex) count is not a multiple of 3.
pub(crate) fn claim(
    primitive: &gltf::Primitive,
    what: &str,
    warnings: &mut Vec<String>,
) -> Result<Option<Claim>> {
    let mode = primitive.mode();
    if !matches!(
        mode,
        Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
    ) {
        warnings.push(format!(
            "{what}: mode {mode:?} skipped (only triangles, strips and fans are drawn)"
        ));
        return Ok(None);
    }
    let Some(positions) = primitive.get(&Semantic::Positions) else {
        warnings.push(format!("{what}: no POSITION attribute; skipped"));
        return Ok(None);
    };
    let vertices = positions.count() as u64;
    let n = primitive.indices().map_or(vertices, |i| i.count() as u64);
    let triangles = match mode {
        Mode::Triangles => {
            if !n.is_multiple_of(3) {
                return Err(Error::format(format!(
                    "{what}: TRIANGLES with {n} {}, not a multiple of 3",
                    if primitive.indices().is_some() {
                        "indices"
                    } else {
                        "vertices"
                    }
                )));
            }
            n / 3
        }
        _ => n.saturating_sub(2),
    };
    Ok(Some(Claim {
        vertices,
        triangles,
    }))
}

/// Bytes one vertex may take in the output (position, normal, tangent, two UV sets, colour).
pub(crate) const MAX_VERTEX_BYTES: u64 = 12 + 12 + 16 + 8 + 8 + 16;

/// Everything needed to build primitives.
pub(crate) struct Context<'a> {
    pub(crate) buffers: &'a Buffers,
    pub(crate) limits: &'a LoadLimits,
}

/// Reads one primitive of a mesh instance and returns it flattened into the instance's world
/// space as a triangle list, with normals (and tangents when `wants_tangents_from` names the UV
/// set of a normal map) complete.
///
/// # Errors
/// `Format` naming the primitive and accessor for bad data (out-of-range index, non-finite
/// position, attribute count mismatch, wrong accessor type).
#[allow(clippy::too_many_arguments)]
pub(crate) fn build(
    ctx: &Context,
    instance: &MeshInstance,
    primitive: &gltf::Primitive,
    what: &str,
    material: usize,
    wants_tangents_from: Option<u32>,
    warnings: &mut Vec<String>,
    budget: &mut MemoryBudget,
) -> Result<Primitive> {
    let max_vertices = ctx.limits.max_vertices;
    let pos_acc = primitive
        .get(&Semantic::Positions)
        .ok_or_else(|| Error::Internal(format!("{what}: POSITION vanished after planning")))?;
    let (raw, _) = read_floats(
        &pos_acc,
        ctx.buffers,
        &[Dimensions::Vec3],
        max_vertices,
        &format!("{what} POSITION"),
        budget,
    )?;
    let vertex_count = pos_acc.count();
    let world = instance.world;
    let mut positions = Vec::with_capacity(vertex_count);
    for (i, p) in raw.chunks_exact(3).enumerate() {
        let p = Vec3::new(p[0], p[1], p[2]);
        if !p.is_finite() {
            return Err(Error::format(format!(
                "{what} POSITION (accessor {}): vertex {i} is not finite ({p})",
                pos_acc.index()
            )));
        }
        let w = world.transform_point3(p);
        if !w.is_finite() {
            return Err(Error::format(format!(
                "{what}: vertex {i} overflows once transformed to world space"
            )));
        }
        positions.push(w);
    }
    drop(raw);

    // Every other attribute must describe the same vertices.
    for (semantic, accessor) in primitive.attributes() {
        if accessor.count() != vertex_count {
            return Err(Error::format(format!(
                "{what}: attribute {semantic:?} (accessor {}) has {} elements but POSITION has \
                 {vertex_count}",
                accessor.index(),
                accessor.count()
            )));
        }
    }

    let max_indices = mul(ctx.limits.max_triangles, 3, "index cap")?;
    let source_indices: Vec<u32> = match primitive.indices() {
        Some(acc) => read_indices(&acc, ctx.buffers, vertex_count, max_indices, what, budget)?,
        None => (0..vertex_count as u32).collect(),
    };
    let mut indices = to_triangle_list(primitive.mode(), &source_indices);
    drop(source_indices);
    let det = Mat3::from_mat4(world).determinant();
    if det < 0.0 {
        // A mirroring transform turns counter-clockwise front faces clockwise; restore them.
        for t in indices.chunks_exact_mut(3) {
            t.swap(1, 2);
        }
    }

    let normal_matrix = Mat3::from_mat4(world).inverse().transpose();
    let normal_matrix_ok = det.abs() > 1e-30 && normal_matrix.is_finite();
    let normals = match primitive.get(&Semantic::Normals) {
        Some(acc) => {
            let (raw, _) = read_floats(
                &acc,
                ctx.buffers,
                &[Dimensions::Vec3],
                max_vertices,
                &format!("{what} NORMAL"),
                budget,
            )?;
            let mut normals: Vec<Vec3> = raw
                .chunks_exact(3)
                .map(|c| {
                    if normal_matrix_ok {
                        let file = Vec3::new(c[0], c[1], c[2]);
                        // Keep the file's length: a zero or short normal must stay detectable.
                        (normal_matrix * file).normalize_or_zero() * file.length().min(2.0)
                    } else {
                        Vec3::ZERO
                    }
                })
                .collect();
            let (replaced, renormalised) =
                attributes::repair_normals(&mut normals, &positions, &indices);
            if replaced > 0 {
                warnings.push(format!(
                    "{what}: {replaced} of {vertex_count} normals were zero or not finite; \
                     recomputed from the faces (area-weighted)"
                ));
            }
            if renormalised > 0 {
                warnings.push(format!(
                    "{what}: {renormalised} of {vertex_count} normals were not unit length; \
                     renormalised"
                ));
            }
            normals
        }
        None => {
            warnings.push(format!(
                "{what}: no NORMAL attribute; normals computed from the faces (area-weighted)"
            ));
            attributes::area_weighted_normals(&positions, &indices)
        }
    };

    let uv0 = read_uv(ctx, primitive, 0, what, warnings, budget)?;
    let uv1 = read_uv(ctx, primitive, 1, what, warnings, budget)?;
    let colors = read_colors(ctx, primitive, what, warnings, budget)?;

    let tangents = match wants_tangents_from {
        None => None,
        Some(set) => {
            let uvs = match set {
                0 => uv0.as_deref(),
                1 => uv1.as_deref(),
                _ => None,
            };
            let from_file = match primitive.get(&Semantic::Tangents) {
                Some(acc) => {
                    let (raw, _) = read_floats(
                        &acc,
                        ctx.buffers,
                        &[Dimensions::Vec4],
                        max_vertices,
                        &format!("{what} TANGENT"),
                        budget,
                    )?;
                    let upper = Mat3::from_mat4(world);
                    let sign = if det < 0.0 { -1.0 } else { 1.0 };
                    let t: Vec<Vec4> = raw
                        .chunks_exact(4)
                        .map(|t| {
                            let xyz = (upper * Vec3::new(t[0], t[1], t[2])).normalize_or_zero();
                            let w = if t[3] < 0.0 { -sign } else { sign };
                            xyz.extend(w)
                        })
                        .collect();
                    if t.iter().all(|t| t.truncate() != Vec3::ZERO) {
                        Some(t)
                    } else {
                        warnings.push(format!(
                            "{what}: TANGENT (accessor {}) has zero or non-finite tangents; \
                             regenerated",
                            acc.index()
                        ));
                        None
                    }
                }
                None => None,
            };
            match (from_file, uvs) {
                (Some(t), _) => Some(t),
                (None, Some(uvs)) => Some(attributes::generate_tangents(
                    &positions, &normals, uvs, &indices,
                )),
                (None, None) => {
                    warnings.push(format!(
                        "{what}: the normal map reads TEXCOORD_{set}, which the primitive lacks; \
                         tangents are arbitrary"
                    ));
                    Some(attributes::generate_tangents(
                        &positions,
                        &normals,
                        &vec![Vec2::ZERO; vertex_count],
                        &indices,
                    ))
                }
            }
        }
    };

    let bounds = Aabb::from_points(&positions).unwrap_or(Aabb::ZERO);
    Ok(Primitive {
        mesh: instance.mesh.index(),
        mesh_name: instance.mesh.name().map(str::to_string),
        node: instance.node.index(),
        primitive: primitive.index(),
        positions,
        normals,
        tangents,
        uv0,
        uv1,
        colors,
        indices,
        material,
        bounds,
    })
}

fn read_uv(
    ctx: &Context,
    primitive: &gltf::Primitive,
    set: u32,
    what: &str,
    warnings: &mut Vec<String>,
    budget: &mut MemoryBudget,
) -> Result<Option<Vec<Vec2>>> {
    let Some(acc) = primitive.get(&Semantic::TexCoords(set)) else {
        return Ok(None);
    };
    let (raw, _) = read_floats(
        &acc,
        ctx.buffers,
        &[Dimensions::Vec2],
        ctx.limits.max_vertices,
        &format!("{what} TEXCOORD_{set}"),
        budget,
    )?;
    let mut bad = 0;
    let uv = raw
        .chunks_exact(2)
        .map(|t| {
            let v = Vec2::new(t[0], t[1]);
            if v.is_finite() {
                v
            } else {
                bad += 1;
                Vec2::ZERO
            }
        })
        .collect();
    if bad > 0 {
        warnings.push(format!(
            "{what} TEXCOORD_{set} (accessor {}): {bad} non-finite coordinates set to 0",
            acc.index()
        ));
    }
    Ok(Some(uv))
}

fn read_colors(
    ctx: &Context,
    primitive: &gltf::Primitive,
    what: &str,
    warnings: &mut Vec<String>,
    budget: &mut MemoryBudget,
) -> Result<Option<Vec<Vec4>>> {
    let Some(acc) = primitive.get(&Semantic::Colors(0)) else {
        return Ok(None);
    };
    let (raw, n) = read_floats(
        &acc,
        ctx.buffers,
        &[Dimensions::Vec3, Dimensions::Vec4],
        ctx.limits.max_vertices,
        &format!("{what} COLOR_0"),
        budget,
    )?;
    let mut bad = 0;
    let colors = raw
        .chunks_exact(n)
        .map(|c| {
            let v = Vec4::new(c[0], c[1], c[2], if n == 4 { c[3] } else { 1.0 });
            if v.is_finite() && v.cmpge(Vec4::ZERO).all() && v.cmple(Vec4::ONE).all() {
                v
            } else {
                bad += 1;
                if v.is_finite() {
                    v.clamp(Vec4::ZERO, Vec4::ONE)
                } else {
                    Vec4::ONE
                }
            }
        })
        .collect();
    if bad > 0 {
        warnings.push(format!(
            "{what} COLOR_0 (accessor {}): {bad} colours outside [0, 1] or not finite; clamped",
            acc.index()
        ));
    }
    Ok(Some(colors))
}

/// Triangles, strips and fans as a triangle list with the winding the spec defines (§3.7.2.1).
pub(crate) fn to_triangle_list(mode: Mode, idx: &[u32]) -> Vec<u32> {
    match mode {
        Mode::Triangles => idx.to_vec(),
        Mode::TriangleStrip => {
            let mut out = Vec::with_capacity(idx.len().saturating_sub(2) * 3);
            for i in 0..idx.len().saturating_sub(2) {
                if i % 2 == 0 {
                    out.extend_from_slice(&[idx[i], idx[i + 1], idx[i + 2]]);
                } else {
                    out.extend_from_slice(&[idx[i + 1], idx[i], idx[i + 2]]);
                }
            }
            out
        }
        Mode::TriangleFan => {
            let mut out = Vec::with_capacity(idx.len().saturating_sub(2) * 3);
            for i in 0..idx.len().saturating_sub(2) {
                out.extend_from_slice(&[idx[i + 1], idx[i + 2], idx[0]]);
            }
            out
        }
        _ => Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strips_alternate_winding_and_fans_pivot_on_the_first_vertex() {
        assert_eq!(
            to_triangle_list(Mode::TriangleStrip, &[0, 1, 2, 3, 4]),
            vec![0, 1, 2, 2, 1, 3, 2, 3, 4]
        );
        assert_eq!(
            to_triangle_list(Mode::TriangleFan, &[0, 1, 2, 3]),
            vec![1, 2, 0, 2, 3, 0]
        );
        assert!(to_triangle_list(Mode::TriangleStrip, &[0, 1]).is_empty());
        assert!(to_triangle_list(Mode::TriangleFan, &[]).is_empty());
    }

    #[test]
    fn strip_triangles_all_face_the_same_way() {
        // A zig-zag strip in the z = 0 plane: every output triangle must be CCW from +Z.
        let p = [
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(2.0, 1.0, 0.0),
        ];
        let list = to_triangle_list(Mode::TriangleStrip, &[0, 1, 2, 3, 4]);
        for t in list.chunks_exact(3) {
            let [a, b, c] = [p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]];
            assert!((b - a).cross(c - a).z > 0.0, "{t:?}");
        }
    }
}
