//! Unidirectional path tracing with next-event estimation and multiple importance sampling.
//!
//! At every surface vertex each light (and the environment, when it emits) is sampled once and
//! the BRDF once; both strategies are weighted with the power heuristic, so area lights, the sun
//! disc and the environment are all found by both. Paths stop at the bounce limit or by Russian
//! roulette after three bounces. Each sample of each pixel draws from its own generator seeded by
//! (seed, view, pixel, sample index), so the image does not depend on the thread count; rayon
//! spreads bands of rows over the threads.

use glam::{DVec3, Vec3A};
use rayon::prelude::*;

use super::brdf::Brdf;
use super::geometry::{plane_distance_f64, Geometry, SurfaceHit};
use super::lights::{Emitter, EnvLight};
use super::sampling::{power_heuristic, Frame, Rng};

/// Rows per unit of parallel work.
const BAND_ROWS: usize = 4;
/// Bounces before Russian roulette may end a path.
const ROULETTE_AFTER: u32 = 3;

fn luminance(c: Vec3A) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// Pushes a ray origin off the surface along the geometric normal, relative to the coordinates'
/// magnitude so that f32 rounding cannot put it back behind the surface.
fn offset(p: Vec3A, n: Vec3A) -> Vec3A {
    p + n * (2e-5 * (1.0 + p.abs().max_element()))
}

/// The rectified rig in world space.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Camera {
    /// Left and right camera centres.
    pub eyes: [Vec3A; 2],
    pub right: Vec3A,
    pub up: Vec3A,
    pub forward: Vec3A,
    pub focal: f64,
    pub cx: f64,
    pub cy: f64,
    pub width: usize,
    pub height: usize,
    pub baseline: f64,
}

impl Camera {
    /// The (unnormalised) world direction through image point (px, py) whose component along
    /// `forward` is 1: `(u − cx)/f · right − (v − cy)/f · down… ` i.e. camera ((u−cx)/f, −(v−cy)/f, −1).
    pub(crate) fn direction(&self, px: f64, py: f64) -> DVec3 {
        let dx = (px - self.cx) / self.focal;
        let dy = -(py - self.cy) / self.focal;
        let r = DVec3::from(Vec3A::to_array(&self.right).map(f64::from));
        let u = DVec3::from(Vec3A::to_array(&self.up).map(f64::from));
        let f = DVec3::from(Vec3A::to_array(&self.forward).map(f64::from));
        r * dx + u * dy + f
    }

    /// World vector → camera frame (x right, y up, z backwards).
    pub(crate) fn to_camera(self, v: Vec3A) -> Vec3A {
        Vec3A::new(v.dot(self.right), v.dot(self.up), -v.dot(self.forward))
    }
}

/// Everything a ray can hit, and the lights.
pub(crate) struct Tracer {
    pub geometry: Geometry,
    pub emitters: Vec<Emitter>,
    pub env: EnvLight,
    pub camera: Camera,
    pub max_bounces: u32,
}

/// What a closest-hit query found.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Hit {
    Surface(SurfaceHit),
    Light(usize, f32),
    Miss,
}

/// Per-pixel running sums over samples.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct PixelSums {
    pub rgb: [f64; 3],
    pub luminance: f64,
    pub luminance_sq: f64,
    /// Samples whose primary ray hit an inserted object.
    pub inserted: u32,
}

/// Per pixel and light: Σ visibility·weight and Σ weight of the primary vertex's light samples.
pub(crate) type ShadowSums = [f64; 2];

/// Ray counts of a pass.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct RayCounts {
    pub closest: u64,
    pub shadow: u64,
}

impl std::ops::Add for RayCounts {
    type Output = RayCounts;
    fn add(self, o: RayCounts) -> RayCounts {
        RayCounts {
            closest: self.closest + o.closest,
            shadow: self.shadow + o.shadow,
        }
    }
}

/// Ground truth of one pixel centre of the left view.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PixelTruth {
    /// Depth along the optical axis, metres (NaN: nothing hit).
    pub depth: f64,
    /// Unit normal in the camera frame, facing the camera (zero: nothing hit).
    pub normal: Vec3A,
    /// Visible from the right camera too.
    pub visible_right: bool,
}

impl Tracer {
    pub(crate) fn light_count(&self) -> usize {
        self.emitters.len()
    }

    /// Nearest surface or light along `o + t·d` (d unit), counting the query.
    pub(crate) fn closest(&self, o: Vec3A, d: Vec3A, tmax: f32, counts: &mut RayCounts) -> Hit {
        counts.closest += 1;
        let surface = self.geometry.intersect(o, d, tmax);
        let mut best_t = surface.map_or(tmax, |h| h.t);
        let mut best = surface.map_or(Hit::Miss, Hit::Surface);
        for (i, e) in self.emitters.iter().enumerate() {
            if let Some(t) = e.intersect(o, d, best_t) {
                best_t = t;
                best = Hit::Light(i, t);
            }
        }
        best
    }

    /// One path through image point (px, py) of `view` (0 left, 1 right). Returns the radiance
    /// and whether the primary ray hit an inserted object. When `shadow` is given, the primary
    /// vertex's light samples add their visibility to it (one entry per light).
    pub(crate) fn trace(
        &self,
        view: usize,
        px: f64,
        py: f64,
        rng: &mut Rng,
        mut shadow: Option<&mut [ShadowSums]>,
        counts: &mut RayCounts,
    ) -> (Vec3A, bool) {
        let dir = self.camera.direction(px, py);
        let mut d = Vec3A::new(dir.x as f32, dir.y as f32, dir.z as f32).normalize();
        let mut o = self.camera.eyes[view];
        let mut throughput = Vec3A::ONE;
        let mut radiance = Vec3A::ZERO;
        // Density of the BRDF sample that produced the current ray; 0 for the camera ray, whose
        // hits on emitters are not weighted.
        let mut prev_pdf = 0.0f32;
        let mut inserted = false;
        let env_sampled = !self.env.is_black();
        let mut bounce = 0u32;
        loop {
            match self.closest(o, d, f32::INFINITY, counts) {
                Hit::Miss => {
                    let le = self.env.radiance(d);
                    let w = if prev_pdf > 0.0 && env_sampled {
                        power_heuristic(prev_pdf, self.env.pdf(d))
                    } else {
                        1.0
                    };
                    radiance += throughput * le * w;
                    for e in &self.emitters {
                        if let Some((le, light_pdf)) = e.escaped(d) {
                            let w = if prev_pdf > 0.0 {
                                power_heuristic(prev_pdf, light_pdf)
                            } else {
                                1.0
                            };
                            radiance += throughput * le * w;
                        }
                    }
                    break;
                }
                Hit::Light(i, t) => {
                    let (le, light_pdf) = self.emitters[i].hit(o, d, t);
                    let w = if prev_pdf > 0.0 {
                        power_heuristic(prev_pdf, light_pdf)
                    } else {
                        1.0
                    };
                    radiance += throughput * le * w;
                    break;
                }
                Hit::Surface(hit) => {
                    let sp = self.geometry.surface_point(o, d, hit);
                    let material = self.geometry.material(sp.object);
                    if bounce == 0 {
                        inserted = self.geometry.is_inserted(sp.object);
                    }
                    radiance += throughput * Vec3A::from(material.emission);
                    if bounce >= self.max_bounces {
                        break;
                    }
                    let ng = sp.geometric_normal;
                    let frame = Frame::new(sp.shading_normal);
                    let wo = frame.to_local(-d);
                    let brdf = Brdf::new(
                        sp.base_color,
                        material.metallic,
                        material.roughness,
                        material.specular,
                    );
                    let origin = offset(sp.position, ng);
                    let record = if bounce == 0 { shadow.take() } else { None };
                    radiance += throughput
                        * self.direct_light(
                            &sp.position,
                            origin,
                            ng,
                            &frame,
                            wo,
                            &brdf,
                            rng,
                            record,
                            counts,
                        );

                    let lobe = rng.uniform();
                    let u = rng.uniform2();
                    let Some((wi_local, f, pdf)) = brdf.sample(wo, lobe, u) else {
                        break;
                    };
                    let wi = frame.to_world(wi_local);
                    if wi.dot(ng) <= 0.0 {
                        break;
                    }
                    throughput *= f * (wi_local.z / pdf);
                    prev_pdf = pdf;
                    bounce += 1;
                    if bounce >= ROULETTE_AFTER {
                        let q = throughput.max_element().min(0.95);
                        if q <= 0.0 || rng.uniform() >= q {
                            break;
                        }
                        throughput /= q;
                    }
                    o = origin;
                    d = wi;
                }
            }
        }
        if radiance.is_finite() {
            (radiance.max(Vec3A::ZERO), inserted)
        } else {
            (Vec3A::ZERO, inserted)
        }
    }

    /// Next-event estimation at a surface point: one sample of every light and of the
    /// environment, MIS-weighted against BRDF sampling.
    #[allow(clippy::too_many_arguments)]
    fn direct_light(
        &self,
        p: &Vec3A,
        origin: Vec3A,
        ng: Vec3A,
        frame: &Frame,
        wo: Vec3A,
        brdf: &Brdf,
        rng: &mut Rng,
        mut record: Option<&mut [ShadowSums]>,
        counts: &mut RayCounts,
    ) -> Vec3A {
        let mut sum = Vec3A::ZERO;
        for (i, e) in self.emitters.iter().enumerate() {
            let u = rng.uniform2();
            let Some(s) = e.sample(*p, u) else { continue };
            let front = s.wi.dot(ng) > 0.0;
            let wi = frame.to_local(s.wi);
            let (f, brdf_pdf) = if front {
                brdf.eval(wo, wi)
            } else {
                (Vec3A::ZERO, 0.0)
            };
            let contributes = front && wi.z > 0.0 && f != Vec3A::ZERO && s.le != Vec3A::ZERO;
            let recording = record.is_some();
            if !(contributes || recording && front) {
                if let Some(r) = record.as_deref_mut() {
                    r[i][1] += (luminance(s.le) / s.pdf) as f64;
                }
                continue;
            }
            counts.shadow += 1;
            let visible = !self.geometry.occluded(origin, s.wi, s.dist * (1.0 - 1e-4));
            if let Some(r) = record.as_deref_mut() {
                let w = (luminance(s.le) / s.pdf) as f64;
                r[i][1] += w;
                if visible {
                    r[i][0] += w;
                }
            }
            if contributes && visible {
                let w = if s.delta {
                    1.0
                } else {
                    power_heuristic(s.pdf, brdf_pdf)
                };
                sum += f * s.le * (wi.z * w / s.pdf);
            }
        }
        if !self.env.is_black() {
            let u = rng.uniform2();
            if let Some((wi_world, le, pdf)) = self.env.sample(u) {
                let wi = frame.to_local(wi_world);
                if wi_world.dot(ng) > 0.0 && wi.z > 0.0 {
                    let (f, brdf_pdf) = brdf.eval(wo, wi);
                    if f != Vec3A::ZERO && le != Vec3A::ZERO {
                        counts.shadow += 1;
                        if !self.geometry.occluded(origin, wi_world, f32::INFINITY) {
                            sum += f * le * (wi.z * power_heuristic(pdf, brdf_pdf) / pdf);
                        }
                    }
                }
            }
        }
        sum
    }

    /// Adds samples `first..last` of every pixel of `view` to `sums` (and the primary-vertex
    /// light visibility to `shadow`, `light_count` entries per pixel, when given).
    pub(crate) fn render_pass(
        &self,
        view: usize,
        seed: u64,
        first: u32,
        last: u32,
        sums: &mut [PixelSums],
        shadow: Option<&mut [ShadowSums]>,
    ) -> RayCounts {
        let w = self.camera.width;
        let nl = self.light_count();
        let band = BAND_ROWS * w;
        let work = |(band_index, (pixels, mut shadow_band)): (
            usize,
            (&mut [PixelSums], Option<&mut [ShadowSums]>),
        )| {
            let mut counts = RayCounts::default();
            for (k, acc) in pixels.iter_mut().enumerate() {
                let index = band_index * band + k;
                let (x, y) = (index % w, index / w);
                for s in first..last {
                    let mut rng = Rng::for_sample(seed, view as u64, index as u64, s as u64);
                    let j = rng.uniform2();
                    let pixel_shadow = shadow_band
                        .as_deref_mut()
                        .map(|sh| &mut sh[k * nl..(k + 1) * nl]);
                    let (l, inserted) = self.trace(
                        view,
                        x as f64 + j.x as f64,
                        y as f64 + j.y as f64,
                        &mut rng,
                        pixel_shadow,
                        &mut counts,
                    );
                    let lum = luminance(l) as f64;
                    acc.rgb[0] += l.x as f64;
                    acc.rgb[1] += l.y as f64;
                    acc.rgb[2] += l.z as f64;
                    acc.luminance += lum;
                    acc.luminance_sq += lum * lum;
                    acc.inserted += inserted as u32;
                }
            }
            counts
        };
        match shadow {
            Some(shadow) if nl > 0 => sums
                .par_chunks_mut(band)
                .zip(shadow.par_chunks_mut(band * nl))
                .map(|(a, b)| (a, Some(b)))
                .enumerate()
                .map(work)
                .reduce(RayCounts::default, |a, b| a + b),
            _ => sums
                .par_chunks_mut(band)
                .map(|a| (a, None))
                .enumerate()
                .map(work)
                .reduce(RayCounts::default, |a, b| a + b),
        }
    }

    /// Exact depth, normal and right-view visibility at every pixel centre of the left view.
    pub(crate) fn ground_truth(&self) -> (Vec<PixelTruth>, RayCounts) {
        let cam = &self.camera;
        let (w, h) = (cam.width, cam.height);
        let results: Vec<(Vec<PixelTruth>, RayCounts)> = (0..h)
            .into_par_iter()
            .map(|y| {
                let mut counts = RayCounts::default();
                let row = (0..w)
                    .map(|x| self.pixel_truth(x as f64 + 0.5, y as f64 + 0.5, &mut counts))
                    .collect();
                (row, counts)
            })
            .collect();
        let mut counts = RayCounts::default();
        let mut truth = Vec::with_capacity(w * h);
        for (row, c) in results {
            truth.extend(row);
            counts = counts + c;
        }
        (truth, counts)
    }

    fn pixel_truth(&self, px: f64, py: f64, counts: &mut RayCounts) -> PixelTruth {
        let cam = &self.camera;
        let dir = cam.direction(px, py);
        let len = dir.length();
        let d = Vec3A::new(dir.x as f32, dir.y as f32, dir.z as f32).normalize();
        let eye = cam.eyes[0];
        let fwd = DVec3::new(
            cam.forward.x as f64,
            cam.forward.y as f64,
            cam.forward.z as f64,
        );
        let nothing = PixelTruth {
            depth: f64::NAN,
            normal: Vec3A::ZERO,
            visible_right: false,
        };
        let (t_along_dir, normal_world, position) =
            match self.closest(eye, d, f32::INFINITY, counts) {
                Hit::Miss => return nothing,
                Hit::Surface(hit) => {
                    let tri = self.geometry.triangle(hit.triangle);
                    let o = [eye.x as f64, eye.y as f64, eye.z as f64];
                    // t for the unnormalised direction (forward component 1), in f64.
                    let t = plane_distance_f64(tri, o, dir.to_array());
                    let sp = self.geometry.surface_point(eye, d, hit);
                    if !(t.is_finite() && t > 0.0) {
                        return nothing;
                    }
                    (t, sp.shading_normal, sp.position)
                }
                Hit::Light(i, t) => {
                    let p = eye + d * t;
                    let n = match &self.emitters[i] {
                        Emitter::Rect { normal, .. } => *normal,
                        Emitter::Sphere { center, .. } => (p - *center).normalize_or_zero(),
                        Emitter::Directional { .. } => -d,
                    };
                    let n = if n.dot(d) > 0.0 { -n } else { n };
                    (t as f64 / len, n, p)
                }
            };
        let depth = t_along_dir * dir.dot(fwd);
        // Visible from the right camera: nothing between its centre and the point.
        let right_eye = cam.eyes[1];
        let v = position - right_eye;
        let dist = v.length();
        let disparity = cam.focal * cam.baseline / depth;
        let xr = px - disparity;
        let visible_right = xr >= 0.0
            && xr < cam.width as f64
            && dist > 0.0
            && matches!(
                self.closest(right_eye, v / dist, dist * (1.0 - 1e-4), counts),
                Hit::Miss
            );
        PixelTruth {
            depth,
            normal: cam.to_camera(normal_world),
            visible_right,
        }
    }
}
