//! Export of the reconstruction for other tools: depth as PFM (metres) and 16-bit PNG
//! (millimetres), point clouds and meshes as PLY, meshes as OBJ (HoloLens-style spatial-mapping
//! viewers, Blender, MeshLab) and as binary glTF (GLB) with the photo as an unlit texture.

use std::io::Write;
use std::path::Path;

use serde_json::json;

use super::SceneMesh;
use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::image::{linear_to_srgb8, Image, Raster};

fn write_file(path: &Path, bytes: &[u8]) -> Result<()> {
    std::fs::write(path, bytes).map_err(|e| Error::io(path, e))
}

/// Writes depth (metres, NaN = none) as a grey PFM (Middlebury layout; none is written as `inf`).
///
/// # Errors
/// `Io`.
pub fn write_depth_pfm(depth: &Raster<f32>, path: impl AsRef<Path>) -> Result<()> {
    depth.write_pfm(path)
}

/// Writes depth as a 16-bit grey PNG in millimetres (rounded), 0 = no depth; depths beyond
/// 65.535 m are clamped to 65535. Returns how many pixels were clamped.
///
/// # Errors
/// `Io`; `InvalidArgument` for an empty raster.
pub fn write_depth_png_mm(depth: &Raster<f32>, path: impl AsRef<Path>) -> Result<usize> {
    let path = path.as_ref();
    if depth.is_empty() {
        return Err(Error::invalid("depth PNG: the depth map is empty"));
    }
    let mut clamped = 0;
    let mut bytes = Vec::with_capacity(depth.len() * 2);
    for &z in depth.pixels() {
        let mm = if z.is_finite() && z > 0.0 {
            let mm = (z as f64 * 1000.0).round();
            if mm > 65535.0 {
                clamped += 1;
            }
            // A positive depth below 0.5 mm still has depth: 1, never 0 ("none").
            mm.clamp(1.0, 65535.0) as u16
        } else {
            0
        };
        // `image` takes 16-bit samples in native byte order.
        bytes.extend_from_slice(&mm.to_ne_bytes());
    }
    let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    let encoder = image::codecs::png::PngEncoder::new(std::io::BufWriter::new(file));
    image::ImageEncoder::write_image(
        encoder,
        &bytes,
        depth.width() as u32,
        depth.height() as u32,
        image::ExtendedColorType::L16,
    )
    .map_err(|e| Error::format(format!("{}: {e}", path.display())))?;
    Ok(clamped)
}

/// Writes the mesh as binary little-endian PLY: vertices with position, normal and texture
/// coordinates (`s`, `t`, t measured from the photo's bottom as PLY tools expect), triangles.
///
/// # Errors
/// `Io`.
pub fn write_mesh_ply(mesh: &SceneMesh, path: impl AsRef<Path>) -> Result<()> {
    let mut out = Vec::new();
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment parallax scene mesh (metres, camera frame: \
         +X right, +Y up, looking along -Z)\nelement vertex {}\nproperty float x\nproperty float \
         y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty \
         float s\nproperty float t\nelement face {}\nproperty list uchar uint vertex_indices\n\
         end_header\n",
        mesh.positions.len(),
        mesh.triangle_count()
    );
    out.extend_from_slice(header.as_bytes());
    for k in 0..mesh.positions.len() {
        let uv = mesh.uvs.get(k).copied().unwrap_or([0.0; 2]);
        let n = mesh.normals.get(k).copied().unwrap_or([0.0, 0.0, 1.0]);
        for v in mesh.positions[k]
            .iter()
            .chain(&n)
            .chain(&[uv[0], 1.0 - uv[1]])
        {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    for t in mesh.indices.chunks_exact(3) {
        out.push(3);
        for i in t {
            out.extend_from_slice(&i.to_le_bytes());
        }
    }
    write_file(path.as_ref(), &out)
}

/// Writes the depth map's point cloud as binary PLY: one point per pixel with depth, coloured
/// from `photo` (linear RGB, written as sRGB bytes) when given.
///
/// # Errors
/// `SizeMismatch` when depth, camera and photo sizes differ; `Io`.
pub fn write_point_cloud_ply(
    depth: &Raster<f32>,
    camera: &Camera,
    photo: Option<&Raster<[f32; 3]>>,
    path: impl AsRef<Path>,
) -> Result<()> {
    let (w, h) = (depth.width(), depth.height());
    if (w, h) != (camera.width as usize, camera.height as usize) {
        return Err(Error::SizeMismatch(format!(
            "point cloud: depth is {w}x{h}, camera {}x{}",
            camera.width, camera.height
        )));
    }
    if let Some(p) = photo {
        if (p.width(), p.height()) != (w, h) {
            return Err(Error::SizeMismatch(format!(
                "point cloud: depth is {w}x{h}, photo {}x{}",
                p.width(),
                p.height()
            )));
        }
    }
    let mut body = Vec::new();
    let mut count = 0usize;
    for y in 0..h {
        for x in 0..w {
            let Some(p) = camera.unproject(x as f32 + 0.5, y as f32 + 0.5, *depth.get(x, y)) else {
                continue;
            };
            count += 1;
            for v in p.to_array() {
                body.extend_from_slice(&v.to_le_bytes());
            }
            if let Some(photo) = photo {
                body.extend(photo.get(x, y).map(linear_to_srgb8));
            }
        }
    }
    let colour = if photo.is_some() {
        "property uchar red\nproperty uchar green\nproperty uchar blue\n"
    } else {
        ""
    };
    let mut out = format!(
        "ply\nformat binary_little_endian 1.0\ncomment parallax point cloud (metres)\nelement \
         vertex {count}\nproperty float x\nproperty float y\nproperty float z\n{colour}end_header\n"
    )
    .into_bytes();
    out.extend(body);
    write_file(path.as_ref(), &out)
}

/// Writes the mesh as Wavefront OBJ (positions, normals, texture coordinates with v from the
/// bottom, 1-based faces). With `texture` (a path written into the material as given), a `.mtl`
/// file beside the OBJ maps the photo onto it.
///
/// # Errors
/// `Io`.
pub fn write_obj(mesh: &SceneMesh, path: impl AsRef<Path>, texture: Option<&str>) -> Result<()> {
    let path = path.as_ref();
    let mut out = String::with_capacity(mesh.positions.len() * 80 + mesh.indices.len() * 12);
    out.push_str(
        "# parallax scene mesh (metres, camera frame: +X right, +Y up, looking along -Z)\n",
    );
    if let Some(tex) = texture {
        let mtl = path.with_extension("mtl");
        let name = mtl
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        write_file(
            &mtl,
            format!("newmtl photo\nKa 1 1 1\nKd 1 1 1\nKs 0 0 0\nillum 0\nmap_Kd {tex}\n")
                .as_bytes(),
        )?;
        out.push_str(&format!("mtllib {name}\nusemtl photo\n"));
    }
    use std::fmt::Write as _;
    for p in &mesh.positions {
        let _ = writeln!(out, "v {} {} {}", p[0], p[1], p[2]);
    }
    for uv in &mesh.uvs {
        let _ = writeln!(out, "vt {} {}", uv[0], 1.0 - uv[1]);
    }
    for n in &mesh.normals {
        let _ = writeln!(out, "vn {} {} {}", n[0], n[1], n[2]);
    }
    let has_uv = mesh.uvs.len() == mesh.positions.len();
    let has_n = mesh.normals.len() == mesh.positions.len();
    for t in mesh.indices.chunks_exact(3) {
        out.push('f');
        for i in t {
            let i = i + 1;
            match (has_uv, has_n) {
                (true, true) => write!(out, " {i}/{i}/{i}"),
                (true, false) => write!(out, " {i}/{i}"),
                (false, true) => write!(out, " {i}//{i}"),
                (false, false) => write!(out, " {i}"),
            }
            .ok();
        }
        out.push('\n');
    }
    let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    let mut writer = std::io::BufWriter::new(file);
    writer
        .write_all(out.as_bytes())
        .and_then(|_| writer.flush())
        .map_err(|e| Error::io(path, e))
}

/// An encoded image to embed in a GLB.
#[derive(Debug, Clone, PartialEq)]
pub struct GlbTexture {
    /// PNG or JPEG file bytes.
    pub bytes: Vec<u8>,
    /// `image/png` or `image/jpeg`.
    pub mime_type: &'static str,
}

impl GlbTexture {
    /// Encodes a photo as PNG (sRGB, 8-bit RGB).
    ///
    /// # Errors
    /// `Format` if encoding fails.
    pub fn from_image(photo: &Image) -> Result<GlbTexture> {
        let srgb = photo.to_linear_rgb();
        let mut rgb = Vec::with_capacity(srgb.len() * 3);
        for px in srgb.pixels() {
            rgb.extend(px.map(linear_to_srgb8));
        }
        let mut bytes = Vec::new();
        let encoder = image::codecs::png::PngEncoder::new(&mut bytes);
        image::ImageEncoder::write_image(
            encoder,
            &rgb,
            photo.width(),
            photo.height(),
            image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| Error::format(format!("encoding the GLB texture: {e}")))?;
        Ok(GlbTexture {
            bytes,
            mime_type: "image/png",
        })
    }
}

/// The mesh as a binary glTF 2.0 (GLB) file: one mesh with POSITION, NORMAL, TANGENT and
/// TEXCOORD_0, u32 indices, and — with `texture` — an unlit (`KHR_materials_unlit`) material
/// showing the photo, so any glTF viewer shows the photo in 3D.
///
/// # Errors
/// `InvalidArgument` for a mesh without triangles; `TooLarge` beyond the GLB's 4 GiB.
pub fn glb_bytes(mesh: &SceneMesh, texture: Option<&GlbTexture>) -> Result<Vec<u8>> {
    if mesh.indices.is_empty() || mesh.positions.is_empty() {
        return Err(Error::invalid("GLB export: the mesh has no triangles"));
    }
    let n = mesh.positions.len();
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut push_view = |bin: &mut Vec<u8>, data: &[u8], target: Option<u32>| {
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let offset = bin.len();
        bin.extend_from_slice(data);
        let mut v = json!({"buffer": 0, "byteOffset": offset, "byteLength": data.len()});
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        views.push(v);
        views.len() - 1
    };
    const ARRAY_BUFFER: u32 = 34962;
    const ELEMENT_ARRAY_BUFFER: u32 = 34963;
    let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
    for p in &mesh.positions {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let pos = push_view(
        &mut bin,
        bytemuck::cast_slice(&mesh.positions),
        Some(ARRAY_BUFFER),
    );
    let mut accessors = vec![json!({"bufferView": pos, "componentType": 5126, "count": n,
        "type": "VEC3", "min": lo, "max": hi})];
    let mut attributes = json!({"POSITION": 0});
    if mesh.normals.len() == n {
        let v = push_view(
            &mut bin,
            bytemuck::cast_slice(&mesh.normals),
            Some(ARRAY_BUFFER),
        );
        accessors.push(json!({"bufferView": v, "componentType": 5126, "count": n, "type": "VEC3"}));
        attributes["NORMAL"] = json!(accessors.len() - 1);
    }
    if mesh.tangents.len() == n {
        let v = push_view(
            &mut bin,
            bytemuck::cast_slice(&mesh.tangents),
            Some(ARRAY_BUFFER),
        );
        accessors.push(json!({"bufferView": v, "componentType": 5126, "count": n, "type": "VEC4"}));
        attributes["TANGENT"] = json!(accessors.len() - 1);
    }
    if mesh.uvs.len() == n {
        let v = push_view(
            &mut bin,
            bytemuck::cast_slice(&mesh.uvs),
            Some(ARRAY_BUFFER),
        );
        accessors.push(json!({"bufferView": v, "componentType": 5126, "count": n, "type": "VEC2"}));
        attributes["TEXCOORD_0"] = json!(accessors.len() - 1);
    }
    let iv = push_view(
        &mut bin,
        bytemuck::cast_slice(&mesh.indices),
        Some(ELEMENT_ARRAY_BUFFER),
    );
    accessors.push(json!({"bufferView": iv, "componentType": 5125,
        "count": mesh.indices.len(), "type": "SCALAR"}));
    let indices_accessor = accessors.len() - 1;

    let mut doc = json!({
        "asset": {"version": "2.0", "generator": concat!("parallax ", env!("CARGO_PKG_VERSION"))},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "scene"}],
        "meshes": [{"name": "scene", "primitives": [{"attributes": attributes,
            "indices": indices_accessor, "mode": 4}]}],
        "accessors": accessors,
    });
    if let Some(tex) = texture {
        let v = push_view(&mut bin, &tex.bytes, None);
        doc["images"] = json!([{"bufferView": v, "mimeType": tex.mime_type, "name": "photo"}]);
        doc["samplers"] = json!([{"magFilter": 9729, "minFilter": 9987,
            "wrapS": 33071, "wrapT": 33071}]);
        doc["textures"] = json!([{"source": 0, "sampler": 0}]);
        doc["materials"] = json!([{"name": "photo", "doubleSided": true,
            "pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                "metallicFactor": 0.0, "roughnessFactor": 1.0},
            "extensions": {"KHR_materials_unlit": {}}}]);
        doc["extensionsUsed"] = json!(["KHR_materials_unlit"]);
        doc["meshes"][0]["primitives"][0]["material"] = json!(0);
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    doc["bufferViews"] = json!(views);
    doc["buffers"] = json!([{"byteLength": bin.len()}]);
    let mut text =
        serde_json::to_vec(&doc).map_err(|e| Error::Internal(format!("GLB JSON: {e}")))?;
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    let total = 12 + 8 + text.len() + 8 + bin.len();
    let total32 = u32::try_from(total)
        .map_err(|_| Error::TooLarge(format!("GLB of {total} bytes exceeds 4 GiB")))?;
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&total32.to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend(text);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend(bin);
    Ok(out)
}

/// Writes [`glb_bytes`] to a file.
///
/// # Errors
/// As [`glb_bytes`]; `Io`.
pub fn write_glb(
    mesh: &SceneMesh,
    texture: Option<&GlbTexture>,
    path: impl AsRef<Path>,
) -> Result<()> {
    write_file(path.as_ref(), &glb_bytes(mesh, texture)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::{ImageLimits, PixelFormat};
    use crate::mesh::MeshOptions;

    fn small_mesh() -> (SceneMesh, Camera) {
        let camera = Camera::from_focal(50.0, 6, 4).unwrap();
        let depth = Raster::from_fn(6, 4, |x, _| 1.0 + x as f32 * 0.01);
        (
            SceneMesh::from_depth(&depth, &camera, &MeshOptions::default()).unwrap(),
            camera,
        )
    }

    #[test]
    fn depth_png_is_millimetres_with_zero_for_none() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("d.png");
        let depth = Raster::from_vec(4, 1, vec![1.2345, f32::NAN, 70.0, 0.0001]);
        assert_eq!(write_depth_png_mm(&depth, &path).unwrap(), 1);
        let img = image::open(&path).unwrap().into_luma16();
        assert_eq!(img.as_raw(), &vec![1235u16, 0, 65535, 1]);
        let pfm = dir.path().join("d.pfm");
        write_depth_pfm(&depth, &pfm).unwrap();
        let back = Raster::read_pfm(&pfm, &ImageLimits::default()).unwrap();
        assert_eq!(back.pixels()[0], 1.2345);
        assert!(back.pixels()[1].is_nan());
    }

    #[test]
    fn glb_is_valid_gltf_with_the_mesh_and_texture() {
        let (mesh, _) = small_mesh();
        let photo = Image::from_bytes(6, 4, PixelFormat::Rgb8, vec![200u8; 6 * 4 * 3]).unwrap();
        let tex = GlbTexture::from_image(&photo).unwrap();
        let bytes = glb_bytes(&mesh, Some(&tex)).unwrap();
        assert_eq!(bytes.len() % 4, 0);
        let glb = gltf::Gltf::from_slice(&bytes).unwrap();
        let blob = glb.blob.as_deref().unwrap();
        let prim = glb.meshes().next().unwrap().primitives().next().unwrap();
        let reader = prim.reader(|_| Some(blob));
        let positions: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
        assert_eq!(positions, mesh.positions);
        let indices: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
        assert_eq!(indices, mesh.indices);
        let uvs: Vec<[f32; 2]> = reader.read_tex_coords(0).unwrap().into_f32().collect();
        assert_eq!(uvs, mesh.uvs);
        assert_eq!(
            reader.read_tangents().unwrap().count(),
            mesh.positions.len()
        );
        let image = glb.images().next().unwrap();
        let gltf::image::Source::View { view, mime_type } = image.source() else {
            panic!("image not in a buffer view")
        };
        assert_eq!(mime_type, "image/png");
        let png = &blob[view.offset()..view.offset() + view.length()];
        let decoded = image::load_from_memory(png).unwrap().into_rgb8();
        assert_eq!(decoded.dimensions(), (6, 4));
        assert!(glb_bytes(&SceneMesh::default(), None).is_err());
    }

    #[test]
    fn ply_and_obj_hold_every_vertex_and_face() {
        let (mesh, camera) = small_mesh();
        let dir = tempfile::tempdir().unwrap();
        let ply = dir.path().join("m.ply");
        write_mesh_ply(&mesh, &ply).unwrap();
        let bytes = std::fs::read(&ply).unwrap();
        let header_end = bytes
            .windows(11)
            .position(|w| w == b"end_header\n")
            .unwrap()
            + 11;
        let header = std::str::from_utf8(&bytes[..header_end]).unwrap();
        assert!(header.contains(&format!("element vertex {}", mesh.vertex_count())));
        assert!(header.contains(&format!("element face {}", mesh.triangle_count())));
        assert_eq!(
            bytes.len() - header_end,
            mesh.vertex_count() * 32 + mesh.triangle_count() * 13
        );
        let first = f32::from_le_bytes(bytes[header_end..header_end + 4].try_into().unwrap());
        assert_eq!(first, mesh.positions[0][0]);

        let obj = dir.path().join("m.obj");
        write_obj(&mesh, &obj, Some("photo.png")).unwrap();
        let text = std::fs::read_to_string(&obj).unwrap();
        assert_eq!(
            text.lines().filter(|l| l.starts_with("v ")).count(),
            mesh.vertex_count()
        );
        assert_eq!(
            text.lines().filter(|l| l.starts_with("f ")).count(),
            mesh.triangle_count()
        );
        assert!(text.contains("mtllib m.mtl"));
        assert!(std::fs::read_to_string(dir.path().join("m.mtl"))
            .unwrap()
            .contains("map_Kd photo.png"));

        let cloud = dir.path().join("c.ply");
        let depth = Raster::from_vec(
            6,
            4,
            (0..24)
                .map(|i| if i % 5 == 0 { f32::NAN } else { 2.0 })
                .collect(),
        );
        let colours = Raster::filled(6, 4, [1.0f32, 0.0, 0.5]);
        write_point_cloud_ply(&depth, &camera, Some(&colours), &cloud).unwrap();
        let text = String::from_utf8_lossy(&std::fs::read(&cloud).unwrap()).into_owned();
        assert!(text.contains("element vertex 19"));
        assert!(write_point_cloud_ply(&Raster::filled(3, 3, 1.0), &camera, None, &cloud).is_err());
    }
}
