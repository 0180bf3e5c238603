//! glTF artefacts as inserted objects of the reference renderer (`parallax synth --insert
//! FILE.glb@x,y,z[,scale[,yaw]]`).
//!
//! Each primitive of the artefact becomes one [`Object`] with a [`Shape::Mesh`] (positions,
//! triangles and the artefact's normals) and a [`Material`] from its glTF material:
//!
//! - base colour = `baseColorFactor` × the **mean** of the base-colour texture (decoded from sRGB)
//!   × the mean `COLOR_0` when the primitive has vertex colours. The reference meshes carry no
//!   texture coordinates, so a texture's spatial detail is lost; its mean is what a diffuse
//!   surface reflects on average, which keeps the object's brightness (and so its light bounced
//!   onto the scene) right. Alpha (MASK, BLEND) is ignored: the object is opaque.
//! - metallic and roughness = their factors × the mean of the metallic-roughness texture's B and
//!   G channels;
//! - emission = `emissiveFactor` × `KHR_materials_emissive_strength` × the emissive texture's mean.
//!
//! Normal and occlusion maps are not used.

use glam::{Vec3, Vec4};

use super::description::{Material, Object, Shape, Transform};
use crate::artefact::{Artefact, Primitive, Texture};
use crate::error::{Error, Result};
use crate::image::srgb_to_linear;

/// The objects that insert `artefact` into a reference scene: its lowest point rests on
/// `position` (world metres) with its bounding box centred horizontally over it, turned by
/// `yaw_deg` about +Y (through that point), and uniformly scaled so that its largest extent is
/// `size_m` metres — or at the size the file gives (glTF units are metres) when `size_m` is
/// `None`. See the module documentation for how materials are approximated.
///
/// # Errors
/// `InvalidArgument` for an artefact without triangles, a flat one asked for a size (no extent),
/// a size that is not finite and > 0, or a non-finite position or yaw.
pub fn insert_artefact(
    artefact: &Artefact,
    position: [f32; 3],
    size_m: Option<f32>,
    yaw_deg: f32,
) -> Result<Vec<Object>> {
    if !position.iter().all(|c| c.is_finite()) || !yaw_deg.is_finite() {
        return Err(Error::invalid(format!(
            "insert position {position:?} and yaw {yaw_deg} must be finite"
        )));
    }
    if artefact.is_empty() {
        return Err(Error::invalid(format!(
            "{}: the glTF asset has no triangles to insert",
            artefact.source
        )));
    }
    let bounds = artefact.bounds;
    let scale = match size_m {
        None => 1.0,
        Some(s) if !(s.is_finite() && s > 0.0) => {
            return Err(Error::invalid(format!(
                "insert size must be finite and > 0 metres, got {s}"
            )))
        }
        Some(s) => {
            let largest = bounds.size().max_element();
            if !(largest.is_finite() && largest > 0.0) {
                return Err(Error::invalid(format!(
                    "{}: the asset has no extent, so it cannot be scaled to {s} m",
                    artefact.source
                )));
            }
            s / largest
        }
    };
    let base = Vec3::new(bounds.center().x, bounds.min.y, bounds.center().z);
    let transform = Transform {
        translation: position,
        rotation_deg: [yaw_deg, 0.0, 0.0],
        scale: [scale; 3],
    };
    Ok(artefact
        .primitives
        .iter()
        .filter(|p| p.triangle_count() > 0)
        .map(|p| Object {
            name: format!(
                "{} mesh {} primitive {}",
                artefact.source,
                p.mesh_name.clone().unwrap_or_else(|| p.mesh.to_string()),
                p.primitive
            ),
            shape: Shape::Mesh {
                positions: p.positions.iter().map(|v| (*v - base).to_array()).collect(),
                indices: p
                    .indices
                    .chunks_exact(3)
                    .map(|t| [t[0], t[1], t[2]])
                    .collect(),
                normals: Some(p.normals.iter().map(|n| n.to_array()).collect()),
            },
            material: material(artefact, p),
            transform,
        })
        .collect())
}

/// The reference material of one primitive (see the module documentation).
fn material(artefact: &Artefact, primitive: &Primitive) -> Material {
    let m = artefact
        .materials
        .get(primitive.material)
        .cloned()
        .unwrap_or_default();
    let mean = |slot: Option<crate::artefact::TextureRef>, srgb: bool| -> Vec4 {
        slot.and_then(|t| artefact.textures.get(t.texture))
            .map_or(Vec4::ONE, |t| mean_texel(t, srgb))
    };
    let mut base = m.base_color_factor.truncate() * mean(m.base_color_texture, true).truncate();
    if let Some(colors) = primitive.colors.as_ref().filter(|c| !c.is_empty()) {
        let sum: Vec4 = colors.iter().copied().sum();
        base *= (sum / colors.len() as f32).truncate();
    }
    let mr = mean(m.metallic_roughness_texture, false);
    let emission =
        m.emissive_factor * m.emissive_strength * mean(m.emissive_texture, true).truncate();
    Material {
        base_color: base.clamp(Vec3::ZERO, Vec3::ONE).to_array(),
        texture: None,
        metallic: (m.metallic_factor * mr.z).clamp(0.0, 1.0),
        roughness: (m.roughness_factor * mr.y).clamp(0.0, 1.0),
        specular: 1.0,
        emission: emission.max(Vec3::ZERO).to_array(),
    }
}

/// The mean texel of a texture in [0, 1]; RGB decoded from sRGB first when `srgb` (alpha is
/// always linear).
fn mean_texel(texture: &Texture, srgb: bool) -> Vec4 {
    let pixels = texture.image.rgba8.chunks_exact(4);
    let n = pixels.len();
    if n == 0 {
        return Vec4::ONE;
    }
    let decode = |c: u8| {
        let v = c as f32 / 255.0;
        if srgb {
            srgb_to_linear(v)
        } else {
            v
        }
    };
    let sum = pixels.fold([0.0f64; 4], |mut acc, p| {
        for k in 0..3 {
            acc[k] += decode(p[k]) as f64;
        }
        acc[3] += p[3] as f64 / 255.0;
        acc
    });
    Vec4::from_array(sum.map(|s| (s / n as f64) as f32))
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::artefact::{Aabb, LoadOptions, TextureImage, TextureRef};
    use crate::reference::{
        render_composite, CameraRig, Environment, RenderOptions, SampleBudget, Scene,
    };

    fn box_artefact(center: [f32; 3], half: [f32; 3], color: [f32; 4]) -> Artefact {
        let bytes = crate::scene::box_glb(center, half, color);
        Artefact::from_glb_bytes(&bytes, &LoadOptions::default()).unwrap()
    }

    fn world_bounds(objects: &[Object]) -> Aabb {
        let points: Vec<Vec3> = objects
            .iter()
            .flat_map(|o| {
                let m = o.transform.matrix();
                let Shape::Mesh { positions, .. } = &o.shape else {
                    panic!("not a mesh")
                };
                positions
                    .iter()
                    .map(move |p| m.transform_point3(Vec3::from(*p)))
                    .collect::<Vec<_>>()
            })
            .collect();
        Aabb::from_points(&points).unwrap()
    }

    #[test]
    fn lowest_point_rests_on_the_position_at_the_requested_size() {
        // A 0.4 × 0.2 × 0.1 m box whose own origin is far from it.
        let a = box_artefact([3.0, 5.0, -7.0], [0.2, 0.1, 0.05], [0.9, 0.1, 0.1, 1.0]);
        let objects = insert_artefact(&a, [1.0, 0.5, -2.0], Some(0.8), 90.0).unwrap();
        assert_eq!(objects.len(), 1);
        let b = world_bounds(&objects);
        // Scale 2, turned a quarter about +Y: 0.8 m along z, 0.4 m tall, 0.2 m along x.
        let expect_min = Vec3::new(0.9, 0.5, -2.4);
        let expect_max = Vec3::new(1.1, 0.9, -1.6);
        assert!(
            (b.min - expect_min).abs().max_element() < 1e-5
                && (b.max - expect_max).abs().max_element() < 1e-5,
            "{b:?}"
        );
        // Without a size: the file's own size.
        let b = world_bounds(&insert_artefact(&a, [0.0; 3], None, 0.0).unwrap());
        assert!((b.size() - Vec3::new(0.4, 0.2, 0.1)).abs().max_element() < 1e-6);
        assert!(b.min.y.abs() < 1e-6);
        // The material: the factors as they are.
        assert_eq!(objects[0].material.base_color, [0.9, 0.1, 0.1]);
        assert_eq!(objects[0].material.metallic, 0.0);
        assert!((objects[0].material.roughness - 0.9).abs() < 1e-6);

        assert!(insert_artefact(&a, [0.0; 3], Some(0.0), 0.0).is_err());
        assert!(insert_artefact(&a, [f32::NAN, 0.0, 0.0], None, 0.0).is_err());
        let mut empty = a.clone();
        empty.primitives.clear();
        let e = insert_artefact(&empty, [0.0; 3], None, 0.0).unwrap_err();
        assert!(e.to_string().contains("no triangles"), "{e}");
    }

    #[test]
    fn textures_and_vertex_colours_contribute_their_mean() {
        let mut a = box_artefact([0.0; 3], [0.5; 3], [1.0, 0.5, 1.0, 1.0]);
        // Two texels: sRGB 255 and 0 → linear 1 and 0, mean 0.5; the metallic-roughness texture
        // (linear) has G = 102/255 = 0.4 and B = 255.
        a.textures = vec![
            Texture {
                image: Arc::new(TextureImage {
                    width: 2,
                    height: 1,
                    rgba8: vec![255, 255, 255, 255, 0, 0, 0, 255],
                    name: "bw".into(),
                }),
                sampler: Default::default(),
            },
            Texture {
                image: Arc::new(TextureImage {
                    width: 1,
                    height: 1,
                    rgba8: vec![0, 102, 255, 255],
                    name: "mr".into(),
                }),
                sampler: Default::default(),
            },
        ];
        let slot = |texture| {
            Some(TextureRef {
                texture,
                tex_coord: 0,
                transform: None,
            })
        };
        let m = &mut a.materials[0];
        m.base_color_texture = slot(0);
        m.metallic_factor = 1.0;
        m.roughness_factor = 0.5;
        m.metallic_roughness_texture = slot(1);
        m.emissive_factor = Vec3::new(1.0, 2.0, 0.0);
        m.emissive_strength = 3.0;
        m.emissive_texture = slot(0);
        let n = a.primitives[0].positions.len();
        a.primitives[0].colors = Some(vec![Vec4::new(0.5, 1.0, 1.0, 1.0); n]);
        let objects = insert_artefact(&a, [0.0; 3], None, 0.0).unwrap();
        let mat = &objects[0].material;
        let close = |a: [f32; 3], b: [f32; 3]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-6);
        assert!(close(mat.base_color, [0.25, 0.25, 0.5]), "{mat:?}");
        assert!((mat.roughness - 0.2).abs() < 1e-6 && mat.metallic == 1.0);
        assert!(close(mat.emission, [1.5, 3.0, 0.0]), "{mat:?}");
    }

    /// The GLB box renders exactly like the same box built from the reference's own `Box` shape:
    /// same coverage, same colours (same random numbers per pixel).
    #[test]
    fn an_inserted_glb_renders_like_the_equivalent_builtin_box() {
        let scene = Scene {
            name: "floor".into(),
            camera: CameraRig {
                width: 48,
                height: 36,
                fov_x_deg: Some(50.0),
                focal_px: None,
                baseline_m: 0.06,
                position: [0.0, 1.0, 2.0],
                look_at: [0.0, 0.0, 0.0],
                up: [0.0, 1.0, 0.0],
            },
            objects: vec![Object {
                name: "floor".into(),
                shape: Shape::Plane { size: [10.0, 10.0] },
                material: Material::diffuse([0.5; 3]),
                transform: Transform::default(),
            }],
            lights: vec![],
            environment: Environment::Constant { radiance: [1.0; 3] },
            portals: Vec::new(),
        };
        let a = box_artefact([3.0, 5.0, -7.0], [0.2, 0.1, 0.05], [0.8, 0.1, 0.1, 1.0]);
        let glb = insert_artefact(&a, [0.1, 0.0, 0.0], Some(0.8), 0.0).unwrap();
        let builtin = Object {
            name: "box".into(),
            shape: Shape::Box {
                size: [0.8, 0.4, 0.2],
            },
            material: glb[0].material.clone(),
            transform: Transform::at(0.1, 0.2, 0.0),
        };
        let options = RenderOptions {
            samples: SampleBudget::PerPixel(4),
            max_bounces: 2,
            ..RenderOptions::default()
        };
        let from_glb = render_composite(&scene, &glb, &options).unwrap();
        let reference = render_composite(&scene, &[builtin], &options).unwrap();
        let covered: f32 = from_glb.mask.pixels().iter().sum();
        let covered_ref: f32 = reference.mask.pixels().iter().sum();
        assert!(covered > 50.0, "the box covers {covered} pixels");
        assert!(
            (covered - covered_ref).abs() < 0.01 * covered_ref,
            "{covered} vs {covered_ref}"
        );
        let mut differ = 0;
        for (p, q) in from_glb
            .composite
            .pixels()
            .iter()
            .zip(reference.composite.pixels())
        {
            if (0..3).any(|k| (p[k] - q[k]).abs() > 1e-3 * (1.0 + q[k])) {
                differ += 1;
            }
        }
        // Silhouette pixels may take a sample differently (triangle edges split differently).
        assert!(differ <= 20, "{differ} pixels differ");
        // The box's pixels are red: a pixel fully covered has R well above G.
        let (i, _) = from_glb
            .mask
            .pixels()
            .iter()
            .enumerate()
            .find(|(_, m)| **m == 1.0)
            .unwrap();
        let c = from_glb.composite.pixels()[i];
        assert!(c[0] > 2.0 * c[1], "{c:?}");
    }
}
