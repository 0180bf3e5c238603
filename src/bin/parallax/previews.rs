//! Pictures for people: the surfaces, the lights, the normals and the shadow ratio drawn over or
//! beside the photo (`parallax surfaces`, `lights`, `composite --debug-dir`, `demo`).

use glam::{Vec2, Vec3};
use parallax::camera::Camera;
use parallax::image::Raster;
use parallax::light::{LightKind, LightingEstimate};
use parallax::mesh::{SceneMesh, SurfaceOptions, Surfaces};

/// Tints, one per surface (cycled).
const COLOURS: [[f32; 3]; 8] = [
    [0.9, 0.2, 0.2],
    [0.2, 0.8, 0.2],
    [0.2, 0.4, 1.0],
    [1.0, 0.8, 0.1],
    [0.8, 0.2, 0.9],
    [0.1, 0.9, 0.9],
    [1.0, 0.5, 0.1],
    [0.6, 0.6, 0.6],
];

/// The support surfaces over `background`: the pixels on each surface tinted in its colour (the
/// first, largest surface wins) and its image polygon outlined.
pub fn surfaces_preview(
    background: &Raster<[f32; 3]>,
    depth: &Raster<f32>,
    camera: &Camera,
    found: &Surfaces,
) -> Raster<[f32; 3]> {
    let mut out = background.clone();
    let tolerance = SurfaceOptions::default().membership_tolerance();
    for y in 0..out.height().min(depth.height()) {
        for x in 0..out.width().min(depth.width()) {
            let pixel = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            let Some(p) = camera.unproject(pixel.x, pixel.y, *depth.get(x, y)) else {
                continue;
            };
            if let Some(i) = found.surface_at(pixel, p, tolerance) {
                let c = COLOURS[i % COLOURS.len()];
                let px = out.get_mut(x, y);
                for k in 0..3 {
                    px[k] = 0.45 * px[k] + 0.55 * c[k];
                }
            }
        }
    }
    for (i, s) in found.surfaces.iter().enumerate() {
        draw_polygon(&mut out, &s.polygon_image, COLOURS[i % COLOURS.len()]);
    }
    out
}

/// The lighting estimate over the photo: the shadow mask as a blue tint, each positional light
/// as a yellow circle of its size, and a red line from the insertion point towards the main
/// light (0.5 m long, or up to the light).
pub fn lights_preview(
    photo: &Raster<[f32; 3]>,
    estimate: &LightingEstimate,
    camera: &Camera,
) -> Raster<[f32; 3]> {
    let mut out = photo.clone();
    for (c, m) in out
        .pixels_mut()
        .iter_mut()
        .zip(estimate.shadow_mask.pixels())
    {
        let m = m.clamp(0.0, 1.0) * 0.6;
        *c = [
            c[0] * (1.0 - m),
            c[1] * (1.0 - m),
            c[2] * (1.0 - m) + 0.5 * m,
        ];
    }
    let project = |p: Vec3| camera.project(p).map(|(uv, _)| uv);
    for l in &estimate.fit.lights {
        if l.kind == LightKind::Directional {
            continue;
        }
        let p = Vec3::from(l.position);
        if let (Some(c), Some(e)) = (project(p), project(p + Vec3::X * (l.size / 2.0).max(0.02))) {
            circle(&mut out, c, (e - c).length().max(4.0), [1.0, 0.9, 0.0]);
        }
    }
    let point = Vec3::from(estimate.insertion_point);
    let (towards, dist) = estimate.fit.main.towards(point);
    let reach = if dist.is_finite() { dist.min(0.5) } else { 0.5 };
    if let (Some(a), Some(b)) = (project(point), project(point + towards * reach)) {
        line(&mut out, a, b, [1.0, 0.2, 0.1]);
        circle(&mut out, a, 4.0, [1.0, 0.2, 0.1]);
    }
    out
}

/// The scene mesh's vertex normals at their pixels (x, y, z in [−1, 1] as red, green, blue in
/// [0, 1]); black where the mesh has no vertex.
pub fn normals_preview(mesh: &SceneMesh, width: usize, height: usize) -> Raster<[f32; 3]> {
    let mut out = Raster::filled(width, height, [0.0f32; 3]);
    for (uv, n) in mesh.uvs.iter().zip(&mesh.normals) {
        let (x, y) = (uv[0] * width as f32, uv[1] * height as f32);
        if x >= 0.0 && y >= 0.0 && (x as usize) < width && (y as usize) < height {
            *out.get_mut(x as usize, y as usize) = n.map(|v| 0.5 * (v + 1.0));
        }
    }
    out
}

/// Depth as grey (near bright), for previews without a photo.
pub fn grey_depth(depth: &Raster<f32>) -> Raster<[f32; 3]> {
    let (lo, hi) = parallax::camera::valid_depth_range(depth).unwrap_or((1.0, 2.0));
    depth.map(|&z| {
        if z.is_finite() && z > 0.0 {
            let t = if hi > lo { (hi - z) / (hi - lo) } else { 1.0 };
            let g = 0.05 + 0.6 * t * t;
            [g; 3]
        } else {
            [0.0; 3]
        }
    })
}

/// Outline of a polygon, two pixels wide.
fn draw_polygon(out: &mut Raster<[f32; 3]>, poly: &[Vec2], colour: [f32; 3]) {
    for (i, a) in poly.iter().enumerate() {
        line(out, *a, poly[(i + 1) % poly.len()], colour);
    }
}

fn put(out: &mut Raster<[f32; 3]>, x: f32, y: f32, colour: [f32; 3]) {
    if x >= 0.0 && y >= 0.0 && (x as usize) < out.width() && (y as usize) < out.height() {
        *out.get_mut(x as usize, y as usize) = colour;
    }
}

/// A line two pixels wide.
fn line(out: &mut Raster<[f32; 3]>, a: Vec2, b: Vec2, colour: [f32; 3]) {
    let steps = (b - a).length().ceil().clamp(1.0, 100_000.0) as usize;
    for s in 0..=steps {
        let p = a.lerp(b, s as f32 / steps as f32);
        for (dx, dy) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
            put(out, p.x + dx, p.y + dy, colour);
        }
    }
}

fn circle(out: &mut Raster<[f32; 3]>, c: Vec2, r: f32, colour: [f32; 3]) {
    let steps = (r * 8.0).clamp(16.0, 2000.0) as usize;
    for s in 0..steps {
        let a = s as f32 / steps as f32 * std::f32::consts::TAU;
        put(out, c.x + r * a.cos(), c.y + r * a.sin(), colour);
    }
}
