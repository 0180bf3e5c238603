//! Depth map → [`SceneMesh`]: the thesis' grid triangulation (Algorithm 4), improved so that it
//! does not stretch a "rubber sheet" between a foreground object and what lies behind it, and so
//! that missing depth leaves a hole instead of a spike.
//!
//! ## Where the grid is cut
//! Two neighbouring samples `s` pixels apart (1 or √2 grid steps) with depths `z₁`, `z₂` are
//! connected only when
//!
//! `|z₁ − z₂| ≤ min(z₁, z₂) · (s / f · tan θ_max + ε)`
//!
//! The first term is how fast the depth of a *plane* can change between two rays `s / f` radians
//! apart when the plane is seen at `θ_max` from its normal (to first order, `Δz / z = Δα · tan θ`);
//! a jump larger than that can only be a discontinuity (or a surface seen more obliquely than
//! `θ_max`, which the photo holds too few pixels of to matter). `ε` absorbs depth noise (stereo
//! gives roughly constant *relative* noise). A triangle is kept when all three of its edges pass;
//! each grid quad uses the diagonal with the smaller relative depth jump (or the one that keeps
//! more triangles when a corner is missing or cut).
//!
//! ## Normals
//! A normal from the triangles around a vertex sees depth over one pixel, where stereo noise
//! dominates (tens of degrees of error on a floor). Each vertex's normal is instead the normal of
//! a plane fitted robustly to the inverse depth around it, over a neighbourhood that grows with the
//! noise and ignores what lies across a discontinuity (`local_fit`); on exact depth this is the
//! plane's exact normal.

use rayon::prelude::*;

use super::SceneMesh;
use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::image::Raster;

/// How a depth map becomes a mesh.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MeshOptions {
    /// Grid step in pixels: 1 = a vertex per pixel; `k` = a vertex every `k` pixels (point
    /// samples, so a discontinuity is never averaged away). Default 1.
    pub step: u32,
    /// `θ_max`, degrees in (0, 90): the most oblique view of a surface still meshed as continuous.
    /// Default 85°.
    pub max_grazing_angle_deg: f32,
    /// `ε`, the relative depth noise tolerated between neighbours, ≥ 0. Default 0.01 (1 %).
    pub depth_noise: f32,
    /// Simplify to at most this many triangles ([`super::simplify`]); `None` keeps the full grid.
    pub max_triangles: Option<usize>,
    /// Give the vertices on a detected support surface the surface's normal (see
    /// [`super::Surfaces::snap_mesh_normals`]). Default on. Applied by the
    /// [`Scene`](crate::scene::Scene), which detects the surfaces on the unsnapped grid;
    /// [`SceneMesh::from_depth`] alone knows no surfaces and ignores it.
    pub snap_to_surfaces: bool,
}

impl Default for MeshOptions {
    fn default() -> Self {
        MeshOptions {
            step: 1,
            max_grazing_angle_deg: 85.0,
            depth_noise: 0.01,
            max_triangles: None,
            snap_to_surfaces: true,
        }
    }
}

impl MeshOptions {
    /// Checks every field.
    ///
    /// # Errors
    /// `InvalidArgument` naming the bad field.
    pub fn validate(&self) -> Result<()> {
        if self.step == 0 {
            return Err(Error::invalid(
                "mesh options: step must be ≥ 1 pixel, got 0",
            ));
        }
        let a = self.max_grazing_angle_deg;
        if !(a > 0.0 && a < 90.0) {
            return Err(Error::invalid(format!(
                "mesh options: max_grazing_angle_deg must be in (0, 90), got {a}"
            )));
        }
        if !(self.depth_noise.is_finite() && self.depth_noise >= 0.0) {
            return Err(Error::invalid(format!(
                "mesh options: depth_noise must be finite and ≥ 0, got {}",
                self.depth_noise
            )));
        }
        if self.max_triangles == Some(0) {
            return Err(Error::invalid(
                "mesh options: max_triangles must be ≥ 1 when given",
            ));
        }
        Ok(())
    }
}

impl SceneMesh {
    /// Builds the scene mesh of a depth map (metres along the optical axis; NaN, ±inf and ≤ 0 mean
    /// "no depth" and leave holes) seen by `camera`, then simplifies it when
    /// `options.max_triangles` is set.
    ///
    /// # Errors
    /// `SizeMismatch` when the depth map is not the camera's image size; `InvalidArgument` for bad
    /// options or camera, or when no triangle can be formed (no valid depth, an image smaller than
    /// 2×2 samples, or every neighbour pair cut), with the reason in the message; `TooLarge` when
    /// the grid has more than 2³² vertices.
    pub fn from_depth(
        depth: &Raster<f32>,
        camera: &Camera,
        options: &MeshOptions,
    ) -> Result<SceneMesh> {
        options.validate()?;
        camera.validate()?;
        let (w, h) = (depth.width(), depth.height());
        if w != camera.width as usize || h != camera.height as usize {
            return Err(Error::SizeMismatch(format!(
                "depth map is {w}x{h} but the camera's image is {}x{}",
                camera.width, camera.height
            )));
        }
        let valid = depth
            .pixels()
            .iter()
            .filter(|z| z.is_finite() && **z > 0.0)
            .count();
        if valid == 0 {
            return Err(Error::invalid(format!(
                "cannot build a scene mesh: the {w}x{h} depth map has no valid (finite, > 0) depth"
            )));
        }
        let step = options.step as usize;
        let xs = sample_positions(w, step);
        let ys = sample_positions(h, step);
        let (gw, gh) = (xs.len(), ys.len());
        if gw < 2 || gh < 2 {
            return Err(Error::invalid(format!(
                "cannot build a scene mesh: the {w}x{h} depth map gives a {gw}x{gh} grid at step \
                 {step}; a triangle needs at least 2x2 samples"
            )));
        }
        if (gw as u64) * (gh as u64) > u32::MAX as u64 {
            return Err(Error::TooLarge(format!(
                "scene mesh grid {gw}x{gh} exceeds 2^32 vertices; use a larger step"
            )));
        }

        // Sample positions; None where depth is missing or the point is not representable.
        let points: Vec<Option<[f32; 3]>> = (0..gw * gh)
            .into_par_iter()
            .map(|k| {
                let (x, y) = (xs[k % gw], ys[k / gw]);
                camera
                    .unproject(x as f32 + 0.5, y as f32 + 0.5, *depth.get(x, y))
                    .map(|p| p.to_array())
            })
            .collect();
        let z_of = |k: usize| points[k].map(|p| -p[2]);

        let cut = Cutter {
            per_pixel: (options.max_grazing_angle_deg as f64).to_radians().tan()
                / camera.fx.min(camera.fy) as f64,
            noise: options.depth_noise as f64,
        };
        let triangles: Vec<[u32; 3]> = (0..gh - 1)
            .into_par_iter()
            .flat_map_iter(|j| {
                let mut row = Vec::new();
                for i in 0..gw - 1 {
                    let a = j * gw + i;
                    let (b, c, d) = (a + 1, a + gw, a + gw + 1);
                    let (sx, sy) = ((xs[i + 1] - xs[i]) as f64, (ys[j + 1] - ys[j]) as f64);
                    let sd = sx.hypot(sy);
                    let [za, zb, zc, zd] = [z_of(a), z_of(b), z_of(c), z_of(d)];
                    let ab = cut.joined(za, zb, sx);
                    let cd = cut.joined(zc, zd, sx);
                    let ac = cut.joined(za, zc, sy);
                    let bd = cut.joined(zb, zd, sy);
                    let ad = cut.joined(za, zd, sd);
                    let bc = cut.joined(zb, zc, sd);
                    // Counter-clockwise seen from the camera (image y points down, +Y up).
                    let split_ad = [(ac && cd && ad, [a, c, d]), (ad && bd && ab, [a, d, b])];
                    let split_bc = [(ac && bc && ab, [a, c, b]), (bc && cd && bd, [b, c, d])];
                    let kept = |s: &[(bool, [usize; 3]); 2]| s.iter().filter(|t| t.0).count();
                    let use_ad = match kept(&split_ad).cmp(&kept(&split_bc)) {
                        std::cmp::Ordering::Greater => true,
                        std::cmp::Ordering::Less => false,
                        std::cmp::Ordering::Equal => {
                            cut.jump(za, zd).unwrap_or(f64::INFINITY)
                                < cut.jump(zb, zc).unwrap_or(f64::INFINITY)
                        }
                    };
                    let split = if use_ad { split_ad } else { split_bc };
                    for (keep, t) in split {
                        if keep {
                            row.push(t.map(|v| v as u32));
                        }
                    }
                }
                row
            })
            .collect();
        if triangles.is_empty() {
            return Err(Error::invalid(format!(
                "cannot build a scene mesh: {valid} of {} pixels have depth, but no three \
                 neighbouring samples are valid and continuous",
                w * h
            )));
        }

        let mut mesh = SceneMesh {
            positions: points.iter().map(|p| p.unwrap_or([0.0; 3])).collect(),
            normals: Vec::new(),
            tangents: Vec::new(),
            uvs: (0..gw * gh)
                .map(|k| {
                    let (x, y) = (xs[k % gw], ys[k / gw]);
                    [(x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32]
                })
                .collect(),
            indices: triangles.into_iter().flatten().collect(),
        };
        // Drops every sample without depth (each is unused: no triangle touches it).
        mesh.remove_unused_vertices();
        mesh.recompute_normals_and_tangents();
        // Replace the triangle normals (dominated by depth noise at pixel spacing) by robust
        // local plane fits over the full-resolution depth; the triangle normal seeds each fit and
        // stays where no plane fits.
        let pixels: Vec<(usize, usize)> = mesh
            .uvs
            .iter()
            .map(|uv| {
                let x = (uv[0] * w as f32 - 0.5).round().clamp(0.0, (w - 1) as f32);
                let y = (uv[1] * h as f32 - 0.5).round().clamp(0.0, (h - 1) as f32);
                (x as usize, y as usize)
            })
            .collect();
        let start: Vec<Option<glam::Vec3>> = mesh
            .normals
            .iter()
            .map(|n| Some(glam::Vec3::from(*n)))
            .collect();
        let fitted = super::local_fit::fitted_normals(depth, camera, &pixels, &start);
        for (n, f) in mesh.normals.iter_mut().zip(fitted) {
            if let Some(f) = f {
                *n = f.to_array();
            }
        }
        mesh.recompute_tangents_keeping_normals();
        if let Some(budget) = options.max_triangles {
            if mesh.triangle_count() > budget {
                mesh = super::simplify::simplify(&mesh, budget);
            }
        }
        Ok(mesh)
    }
}

/// Sample coordinates `0, step, 2·step, …` plus the last pixel, so the grid covers the image.
fn sample_positions(len: usize, step: usize) -> Vec<usize> {
    let mut v: Vec<usize> = (0..len).step_by(step).collect();
    if let Some(&last) = v.last() {
        if last + 1 != len {
            v.push(len - 1);
        }
    }
    v
}

/// The discontinuity test of the module docs.
struct Cutter {
    /// `tan θ_max / f`, per pixel of separation.
    per_pixel: f64,
    /// `ε`.
    noise: f64,
}

impl Cutter {
    /// Relative depth jump `|z₁ − z₂| / min(z₁, z₂)`, `None` when either depth is missing.
    fn jump(&self, z1: Option<f32>, z2: Option<f32>) -> Option<f64> {
        let (z1, z2) = (z1? as f64, z2? as f64);
        Some((z1 - z2).abs() / z1.min(z2))
    }

    /// Whether two samples `separation_px` apart belong to one continuous surface.
    fn joined(&self, z1: Option<f32>, z2: Option<f32>, separation_px: f64) -> bool {
        self.jump(z1, z2)
            .is_some_and(|j| j <= separation_px * self.per_pixel + self.noise)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn camera(w: u32, h: u32) -> Camera {
        Camera::from_focal(400.0, w, h).unwrap()
    }

    /// Depth of the plane n·p = d along the ray of pixel (x, y).
    fn plane_depth(c: &Camera, n: Vec3, d: f32, x: usize, y: usize) -> f32 {
        let dir = c.unproject(x as f32 + 0.5, y as f32 + 0.5, 1.0).unwrap();
        d / n.dot(dir)
    }

    fn check_invariants(m: &SceneMesh) {
        let n = m.positions.len();
        assert_eq!(m.normals.len(), n);
        assert_eq!(m.tangents.len(), n);
        assert_eq!(m.uvs.len(), n);
        assert_eq!(m.indices.len() % 3, 0);
        assert!(m.indices.iter().all(|&i| (i as usize) < n));
        for k in 0..n {
            assert!(m.positions[k].iter().all(|v| v.is_finite()));
            let nl = Vec3::from(m.normals[k]).length();
            assert!((nl - 1.0).abs() < 1e-4, "normal length {nl}");
            let t = m.tangents[k];
            assert!((Vec3::new(t[0], t[1], t[2]).length() - 1.0).abs() < 1e-4);
            assert!(t[3] == 1.0 || t[3] == -1.0);
        }
    }

    #[test]
    fn fronto_parallel_plane_is_a_full_grid_facing_the_camera() {
        let c = camera(20, 10);
        let depth = Raster::filled(20, 10, 3.0);
        let m = SceneMesh::from_depth(&depth, &c, &MeshOptions::default()).unwrap();
        check_invariants(&m);
        assert_eq!(m.vertex_count(), 200);
        assert_eq!(m.triangle_count(), 2 * 19 * 9);
        for (p, n) in m.positions.iter().zip(&m.normals) {
            assert!((p[2] + 3.0).abs() < 1e-6);
            assert!((Vec3::from(*n) - Vec3::Z).length() < 1e-5);
        }
        // Counter-clockwise from the camera: geometric normals face +Z.
        for t in 0..m.triangle_count() {
            let [a, b, cc] = m.triangle(t);
            assert!((b - a).cross(cc - a).z > 0.0);
        }
        // UV of pixel (x, y) is its centre over the image size.
        assert_eq!(m.uvs[0], [0.5 / 20.0, 0.5 / 10.0]);
        // Tangent along +u (image right = +X), bitangent sign for v pointing down (−Y).
        assert!((Vec3::from_slice(&m.tangents[0][..3]) - Vec3::X).length() < 1e-5);
        assert_eq!(m.tangents[0][3], -1.0);
    }

    #[test]
    fn floor_normals_are_exact() {
        // A floor 1.5 m below the camera, seen looking straight ahead: y = −1.5, normal +Y.
        let c = camera(160, 120);
        let depth = Raster::from_fn(160, 120, |x, y| {
            if y > 62 {
                plane_depth(&c, Vec3::Y, -1.5, x, y)
            } else {
                f32::NAN
            }
        });
        let m = SceneMesh::from_depth(&depth, &c, &MeshOptions::default()).unwrap();
        check_invariants(&m);
        let worst = m
            .normals
            .iter()
            .map(|n| Vec3::from(*n).angle_between(Vec3::Y).to_degrees())
            .fold(0.0f32, f32::max);
        assert!(worst < 0.05, "worst floor normal error {worst}°");
        for p in &m.positions {
            assert!((p[1] + 1.5).abs() < 1e-4);
        }
    }

    /// Median and 90th percentile of angles, degrees.
    fn median_p90(mut v: Vec<f32>) -> (f32, f32) {
        v.sort_by(f32::total_cmp);
        (v[v.len() / 2], v[v.len() * 9 / 10])
    }

    /// Depth of the floor `n · p = −1.5` up to 12 m, seen in stereo with focal length × baseline
    /// `f_b` (px·m) and `disparity_error(x, y)` pixels added to its disparity; NaN elsewhere.
    fn stereo_floor(
        c: &Camera,
        n: Vec3,
        f_b: f32,
        mut disparity_error: impl FnMut(usize, usize) -> f32,
    ) -> Raster<f32> {
        Raster::from_fn(c.width as usize, c.height as usize, |x, y| {
            let z = plane_depth(c, n, -1.5, x, y);
            if !(z > 0.0 && z < 12.0) {
                return f32::NAN;
            }
            let d = f_b / z + disparity_error(x, y);
            if d > 0.0 {
                f_b / d
            } else {
                f32::NAN
            }
        })
    }

    /// Median and 90th percentile of the normals' angles to `n`, degrees.
    fn angle_spread(normals: &[[f32; 3]], n: Vec3) -> (f32, f32) {
        median_p90(
            normals
                .iter()
                .map(|v| Vec3::from(*v).angle_between(n).to_degrees())
                .collect(),
        )
    }

    #[test]
    fn normals_of_a_plane_under_stereo_noise_are_within_a_few_degrees() {
        // A floor 1.5 m below a camera pitched down 20°, seen in stereo (f = 400 px, B = 0.1 m)
        // with Gaussian disparity noise of 0.5 px: σ_Z/Z = 3–6 % at these depths.
        let c = camera(200, 150);
        let n = glam::Mat3::from_rotation_x(20f32.to_radians()) * Vec3::Y;
        let (f_b, sigma_d) = (400.0 * 0.1, 0.5);
        let mut rng = crate::mesh::surfaces::XorShift(11);
        let depth = stereo_floor(&c, n, f_b, |_, _| {
            sigma_d * crate::mesh::local_fit::tests::gaussian(&mut rng)
        });
        let m = SceneMesh::from_depth(&depth, &c, &MeshOptions::default()).unwrap();
        check_invariants(&m);
        let errors = |normals: &[[f32; 3]]| angle_spread(normals, n);
        let (median, p90) = errors(&m.normals);
        assert!(median < 3.0 && p90 < 8.0, "median {median}°, p90 {p90}°");
        // The per-pixel triangle normals this replaces are far off: the test can tell them apart.
        let mut raw = m.clone();
        raw.recompute_normals_and_tangents();
        let (raw_median, _) = errors(&raw.normals);
        assert!(raw_median > 20.0, "triangle normals median {raw_median}°");
    }

    #[test]
    fn normals_of_a_floor_under_correlated_stereo_noise_are_within_a_few_degrees() {
        // As above, but the disparity errors are correlated over 9 px (as a matcher's are after
        // aggregation and smoothing): short differences underrate them, and a fit that trusts
        // them stops growing early and tilts with each bump.
        let c = camera(240, 180);
        let n = glam::Mat3::from_rotation_x(20f32.to_radians()) * Vec3::Y;
        let f_b = 400.0 * 0.1;
        let noise = crate::mesh::local_fit::tests::correlated_noise_field(240, 180, 4, 0.3, 5);
        let depth = stereo_floor(&c, n, f_b, |x, y| *noise.get(x, y));
        let m = SceneMesh::from_depth(&depth, &c, &MeshOptions::default()).unwrap();
        check_invariants(&m);
        let (median, p90) = angle_spread(&m.normals, n);
        assert!(median < 4.0 && p90 < 12.0, "median {median}°, p90 {p90}°");
    }

    #[test]
    fn normals_stay_sharp_at_a_crease_and_a_discontinuity() {
        // A box's top (horizontal, y = −0.5 m, from z = −2 to −3) and front (z = −2, facing the
        // camera) meeting in an edge, in front of a wall at z = −4: exact depth keeps exact
        // normals next to the crease and the cuts.
        let c = Camera::from_focal(100.0, 120, 90).unwrap();
        let depth = Raster::from_fn(120, 90, |x, y| {
            if !(30..90).contains(&x) {
                return 4.0;
            }
            let top_z = plane_depth(&c, Vec3::Y, -0.5, x, y);
            if (y as f32 + 0.5) > c.cy + 0.5 / 2.0 * c.fy {
                2.0
            } else if (2.0..3.0).contains(&top_z) {
                top_z
            } else {
                4.0
            }
        });
        let m = SceneMesh::from_depth(&depth, &c, &MeshOptions::default()).unwrap();
        let region = |z: f32| {
            if z == 4.0 {
                0
            } else if z == 2.0 {
                1
            } else {
                2
            }
        };
        let mut checked = [0; 3];
        for (p, nv) in m.positions.iter().zip(&m.normals) {
            let (p, nv) = (Vec3::from(*p), Vec3::from(*nv));
            let (px, _) = c.project(p).unwrap();
            let (x, y) = (px.x as usize, px.y as usize);
            let k = region(*depth.get(x, y));
            // Only the pixels right at a change of surface are left out.
            let at_change = (x.saturating_sub(1)..=(x + 1).min(119)).any(|xx| {
                (y.saturating_sub(1)..=(y + 1).min(89)).any(|yy| region(*depth.get(xx, yy)) != k)
            });
            if at_change {
                continue;
            }
            let truth = if k == 2 { Vec3::Y } else { Vec3::Z };
            assert!(
                nv.angle_between(truth).to_degrees() < 0.5,
                "pixel ({x}, {y}) region {k}: normal {nv}"
            );
            checked[k] += 1;
        }
        assert!(checked.iter().all(|&n| n > 200), "{checked:?}");
    }

    #[test]
    fn box_in_front_of_a_wall_is_cut_at_its_outline() {
        let c = camera(64, 48);
        let depth = Raster::from_fn(64, 48, |x, y| {
            if (20..40).contains(&x) && (10..30).contains(&y) {
                1.0
            } else {
                3.0
            }
        });
        let m = SceneMesh::from_depth(&depth, &c, &MeshOptions::default()).unwrap();
        check_invariants(&m);
        for t in 0..m.triangle_count() {
            let zs = m.triangle(t).map(|p| -p.z);
            assert!(
                zs.iter().all(|&z| z == 1.0) || zs.iter().all(|&z| z == 3.0),
                "triangle {t} spans the discontinuity: {zs:?}"
            );
        }
        // Both the box (19×19 quads) and the wall around it are meshed.
        let front = (0..m.triangle_count())
            .filter(|&t| m.triangle(t)[0].z == -1.0)
            .count();
        assert_eq!(front, 2 * 19 * 19);
    }

    #[test]
    fn steep_but_continuous_slope_is_kept() {
        // A plane seen at 80° from its normal is still continuous (θ_max = 85°).
        let c = camera(50, 50);
        let n = Vec3::new(80f32.to_radians().sin(), 0.0, 80f32.to_radians().cos());
        let depth = Raster::from_fn(50, 50, |x, y| plane_depth(&c, n, -2.0, x, y));
        let m = SceneMesh::from_depth(&depth, &c, &MeshOptions::default()).unwrap();
        assert_eq!(m.triangle_count(), 2 * 49 * 49);
        let worst = m
            .normals
            .iter()
            .map(|v| Vec3::from(*v).angle_between(n).to_degrees())
            .fold(0.0f32, f32::max);
        assert!(worst < 0.1, "{worst}");
    }

    #[test]
    fn missing_depth_leaves_holes_and_never_propagates() {
        let c = camera(8, 8);
        let bad = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 0.0, -2.0];
        let depth = Raster::from_fn(8, 8, |x, y| if x == 3 { bad[y % 5] } else { 2.0 });
        let m = SceneMesh::from_depth(&depth, &c, &MeshOptions::default()).unwrap();
        check_invariants(&m);
        // Column 3 is missing: no vertex there, and no triangle crosses it.
        assert_eq!(m.vertex_count(), 7 * 8);
        assert_eq!(m.triangle_count(), 2 * 7 * 2 + 2 * 7 * 3);
        for uv in &m.uvs {
            assert!(((uv[0] * 8.0 - 0.5) - 3.0).abs() > 0.1);
        }
    }

    #[test]
    fn block_step_samples_every_kth_pixel_and_the_last() {
        let c = camera(10, 7);
        let depth = Raster::filled(10, 7, 1.0);
        let opts = MeshOptions {
            step: 4,
            ..Default::default()
        };
        let m = SceneMesh::from_depth(&depth, &c, &opts).unwrap();
        // x: 0 4 8 9, y: 0 4 6.
        assert_eq!(m.vertex_count(), 12);
        assert_eq!(m.triangle_count(), 2 * 3 * 2);
        check_invariants(&m);
    }

    #[test]
    fn bad_input_gives_clear_errors() {
        let c = camera(4, 4);
        let all_bad = Raster::from_vec(4, 4, vec![f32::NAN; 16]);
        let e = SceneMesh::from_depth(&all_bad, &c, &MeshOptions::default()).unwrap_err();
        assert!(e.to_string().contains("no valid"), "{e}");
        let wrong = Raster::filled(5, 4, 1.0);
        assert!(matches!(
            SceneMesh::from_depth(&wrong, &c, &MeshOptions::default()),
            Err(Error::SizeMismatch(_))
        ));
        let one = Raster::filled(1, 1, 1.0);
        let e = SceneMesh::from_depth(&one, &camera(1, 1), &MeshOptions::default()).unwrap_err();
        assert!(e.to_string().contains("2x2"), "{e}");
        let line = Raster::filled(7, 1, 1.0);
        assert!(SceneMesh::from_depth(&line, &camera(7, 1), &MeshOptions::default()).is_err());
        let checker = Raster::from_fn(4, 4, |x, y| if (x + y) % 2 == 0 { 1.0 } else { f32::NAN });
        let e = SceneMesh::from_depth(&checker, &c, &MeshOptions::default()).unwrap_err();
        assert!(e.to_string().contains("continuous"), "{e}");
        for bad in [
            MeshOptions {
                step: 0,
                ..Default::default()
            },
            MeshOptions {
                max_grazing_angle_deg: 90.0,
                ..Default::default()
            },
            MeshOptions {
                depth_noise: f32::NAN,
                ..Default::default()
            },
            MeshOptions {
                max_triangles: Some(0),
                ..Default::default()
            },
        ] {
            assert!(SceneMesh::from_depth(&Raster::filled(4, 4, 1.0), &c, &bad).is_err());
        }
    }

    #[test]
    fn extreme_depths_and_fields_of_view_stay_finite() {
        for fov in [1.0, 170.0] {
            let c = Camera::from_fov(fov, 16, 16).unwrap();
            // 1e-40 is subnormal in f32; its inverse is beyond f32.
            for z in [1e-40f32, 1e-30, 1e-6, 1e30, 3e38] {
                let depth = Raster::filled(16, 16, z);
                match SceneMesh::from_depth(&depth, &c, &MeshOptions::default()) {
                    Ok(m) => check_invariants(&m),
                    // Only where x or y would overflow f32 (170° at 3e38 m).
                    Err(e) => assert!(z > 1e38 && e.to_string().contains("continuous"), "{e}"),
                }
            }
        }
    }
}

#[cfg(test)]
mod property_tests {
    use super::*;
    use crate::mesh::surfaces::XorShift;
    use glam::Vec3;

    /// Random depth maps (mixtures of smooth surfaces, steps, noise, holes, non-finite and
    /// extreme values, random sizes, steps and fields of view) never give a NaN, a degenerate
    /// normal or tangent, or an index out of range — before or after simplification.
    #[test]
    fn random_depth_maps_give_valid_meshes() {
        let mut rng = XorShift(0x9e37_79b9_7f4a_7c15);
        let specials = [
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            0.0,
            -1.0,
            1e-30,
            1e30,
            f32::MIN_POSITIVE,
        ];
        let mut built = 0;
        for case in 0..300 {
            let w = 1 + rng.below(40);
            let h = 1 + rng.below(30);
            let fov = [1.0, 30.0, 60.0, 120.0, 170.0][rng.below(5)];
            let camera = Camera::from_fov(fov, w as u32, h as u32).unwrap();
            let base = 0.1 + rng.unit() * 20.0;
            let (gx, gy) = (rng.unit() - 0.5, rng.unit() - 0.5);
            let hole_rate = rng.unit() * 0.5;
            let noise = rng.unit() * 0.2;
            let depth = Raster::from_fn(w, h, |x, y| {
                let r = rng.unit();
                if r < hole_rate * 0.3 {
                    return specials[rng.below(specials.len())];
                }
                let step = if (x + y) % 7 < 3 { base * 0.5 } else { 0.0 };
                (base + gx * x as f32 * 0.1 + gy * y as f32 * 0.1 + step)
                    * (1.0 + noise * (rng.unit() - 0.5))
            });
            let options = MeshOptions {
                step: 1 + rng.below(3) as u32,
                max_grazing_angle_deg: 30.0 + rng.unit() * 59.0,
                depth_noise: rng.unit() * 0.1,
                max_triangles: if rng.below(2) == 0 {
                    Some(1 + rng.below(200))
                } else {
                    None
                },
                ..MeshOptions::default()
            };
            let Ok(mesh) = SceneMesh::from_depth(&depth, &camera, &options) else {
                continue;
            };
            built += 1;
            let n = mesh.positions.len();
            assert!(mesh.triangle_count() > 0, "case {case}");
            assert!(
                mesh.indices.iter().all(|&i| (i as usize) < n),
                "case {case}"
            );
            assert_eq!(
                (mesh.normals.len(), mesh.tangents.len(), mesh.uvs.len()),
                (n, n, n)
            );
            for k in 0..n {
                assert!(
                    mesh.positions[k].iter().all(|v| v.is_finite()),
                    "case {case}"
                );
                assert!(
                    mesh.uvs[k].iter().all(|v| (0.0..=1.0).contains(v)),
                    "case {case}"
                );
                let nl = Vec3::from(mesh.normals[k]);
                assert!(
                    nl.is_finite() && (nl.length() - 1.0).abs() < 1e-3,
                    "case {case}: {nl}"
                );
                let t = mesh.tangents[k];
                let tv = Vec3::new(t[0], t[1], t[2]);
                assert!(
                    tv.is_finite() && (tv.length() - 1.0).abs() < 1e-3,
                    "case {case}"
                );
                assert!(tv.dot(nl).abs() < 1e-3, "case {case}");
                assert!(t[3] == 1.0 || t[3] == -1.0);
            }
            for tri in mesh.indices.chunks_exact(3) {
                assert!(
                    tri[0] != tri[1] && tri[1] != tri[2] && tri[0] != tri[2],
                    "case {case}"
                );
            }
        }
        assert!(built > 100, "only {built} of 300 random maps gave a mesh");
    }
}
