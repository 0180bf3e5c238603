//! Unidirectional path tracing with next-event estimation and multiple importance sampling.
//!
//! At every surface vertex each light (and the environment, when it emits) is sampled once and
//! the BRDF once; both strategies are weighted with the power heuristic, so area lights, the sun
//! disc and the environment are all found by both. When the scene has portals
//! ([`super::portals`]), the environment is also sampled through them, and every directional
//! light once more where its beam lands after passing an opening (the "beam" strategy): the lit
//! point is connected to the shaded point, weighted against finding it by a BRDF bounce followed
//! by the light's own sample there, or by two bounces. Paths stop at the bounce limit or by Russian
//! roulette after three bounces. Each sample of each pixel draws from its own generator seeded by
//! (seed, view, pixel, sample index), so the image does not depend on the thread count; rayon
//! spreads bands of rows over the threads.

use glam::{DVec3, Vec3A};
use rayon::prelude::*;

use super::brdf::Brdf;
use super::geometry::{plane_distance_f64, Geometry, SurfaceHit};
use super::lights::{Emitter, EnvLight, LightSample};
use super::portals::Portals;
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
    /// Openings distant light is sampled through (may be empty).
    pub portals: Portals,
    pub camera: Camera,
    pub max_bounces: u32,
}

/// A surface point ready for light sampling.
struct Shading {
    vertex: Vertex,
    /// Ray origin pushed off the surface.
    origin: Vec3A,
    frame: Frame,
    /// Direction towards the viewer, in `frame`.
    wo: Vec3A,
    brdf: Brdf,
}

/// The surface vertex a BRDF-sampled ray left from: what weighing the beam strategy against the
/// ray's findings needs.
#[derive(Debug, Clone, Copy)]
struct Vertex {
    position: Vec3A,
    geometric_normal: Vec3A,
    /// Density per unit area with which the vertex before it sampled this one (0: the camera's
    /// primary vertex, which the beam strategy cannot produce).
    area_pdf: f32,
}

/// The three ways a path can find light from a distant light that reached a surface point `y`
/// through a portal and was reflected towards the shaded point `x`.
#[derive(Debug, Clone, Copy)]
enum DistantPath {
    /// A BRDF bounce from `x` to `y`, then the light's own sample at `y`.
    BounceThenLight = 0,
    /// The beam strategy: `y` sampled where the beam lands, connected to `x`.
    Beam = 1,
    /// Two BRDF bounces: `x` to `y`, then from `y` into the light's disc.
    TwoBounces = 2,
}

/// Power-heuristic weight of `path` among the three [`DistantPath`]s, from the densities of `y`
/// per unit area as a bounce from `x` gives it (`a`) and as the beam gives it (`b`), and of the
/// light's direction at `y` as the light's sampling gives it (`s`; 1 for a delta light) and as
/// `y`'s BRDF gives it (`c`; 0 for a delta light).
fn distant_path_weight(path: DistantPath, a: f32, b: f32, s: f32, c: f32) -> f32 {
    // In f64: squared products of densities near 1e4 would overflow f32.
    let (a, b, s, c) = (a as f64, b as f64, s as f64, c as f64);
    let products = [a * s, b * s, a * c];
    let sum: f64 = products.iter().map(|p| p * p).sum();
    let w = products[path as usize].powi(2) / sum;
    if w.is_finite() {
        w as f32
    } else {
        0.0
    }
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
        // The surface vertex the current ray left from (None for the camera ray).
        let mut last: Option<Vertex> = None;
        let mut inserted = false;
        let env_sampled = !self.env.is_black();
        let mut bounce = 0u32;
        loop {
            match self.closest(o, d, f32::INFINITY, counts) {
                Hit::Miss => {
                    let le = self.env.radiance(d);
                    let w = match last {
                        Some(v) if prev_pdf > 0.0 && env_sampled => {
                            power_heuristic(prev_pdf, self.env_pdf(v.position, d))
                        }
                        _ => 1.0,
                    };
                    radiance += throughput * le * w;
                    for e in &self.emitters {
                        if let Some((le, light_pdf)) = e.escaped(d) {
                            let w = match last {
                                Some(v) if prev_pdf > 0.0 => self.distant_weight(
                                    DistantPath::TwoBounces,
                                    &v,
                                    d,
                                    light_pdf,
                                    prev_pdf,
                                ),
                                _ => 1.0,
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
                    let here = Vertex {
                        position: sp.position,
                        geometric_normal: ng,
                        area_pdf: match last {
                            Some(_) => prev_pdf * ng.dot(d).abs() / (hit.t * hit.t),
                            None => 0.0,
                        },
                    };
                    let shading = Shading {
                        vertex: here,
                        origin,
                        frame,
                        wo,
                        brdf,
                    };
                    radiance += throughput * self.direct_light(&shading, rng, record, counts);
                    // The beam strategy makes the path two vertices longer: only where a bounce
                    // could have found the same light within the bounce limit.
                    if !self.portals.is_empty() && bounce + 1 < self.max_bounces {
                        radiance += throughput * self.beam_light(&shading, rng, counts);
                    }

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
                    last = Some(here);
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

    /// Density per solid angle of the environment's sample from `p` in direction `d`: its own
    /// importance sampling, or with portals an even mixture of that and sampling through them.
    fn env_pdf(&self, p: Vec3A, d: Vec3A) -> f32 {
        if self.portals.is_empty() {
            self.env.pdf(d)
        } else {
            0.5 * (self.env.pdf(d) + self.portals.direction_pdf(p, d))
        }
    }

    /// MIS weight of `path` for light from a distant light arriving at the vertex `y` along
    /// `to_light`, from the light's sampling density `s` and `y`'s BRDF density `c` for that
    /// direction. Without a beam strategy that could have found `y` (no portals, `y` the
    /// primary vertex, or no opening between `y` and the light) the usual two-way weight.
    fn distant_weight(
        &self,
        path: DistantPath,
        y: &Vertex,
        to_light: Vec3A,
        s: f32,
        c: f32,
    ) -> f32 {
        let b = if self.portals.is_empty() || y.area_pdf <= 0.0 {
            0.0
        } else {
            self.portals
                .beam_area_pdf(y.position, y.geometric_normal, -to_light)
        };
        match path {
            _ if b > 0.0 => distant_path_weight(path, y.area_pdf, b, s, c),
            DistantPath::BounceThenLight => power_heuristic(s, c),
            DistantPath::TwoBounces => power_heuristic(c, s),
            DistantPath::Beam => 0.0,
        }
    }

    /// Next-event estimation at a surface point: one sample of every light and of the
    /// environment, MIS-weighted against BRDF sampling (and, for directional lights with
    /// portals, against the beam strategy).
    fn direct_light(
        &self,
        at: &Shading,
        rng: &mut Rng,
        mut record: Option<&mut [ShadowSums]>,
        counts: &mut RayCounts,
    ) -> Vec3A {
        let (p, ng) = (at.vertex.position, at.vertex.geometric_normal);
        let mut sum = Vec3A::ZERO;
        for (i, e) in self.emitters.iter().enumerate() {
            let u = rng.uniform2();
            let Some(s) = e.sample(p, u) else { continue };
            let front = s.wi.dot(ng) > 0.0;
            let wi = at.frame.to_local(s.wi);
            let (f, brdf_pdf) = if front {
                at.brdf.eval(at.wo, wi)
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
            let visible = !self
                .geometry
                .occluded(at.origin, s.wi, s.dist * (1.0 - 1e-4));
            if let Some(r) = record.as_deref_mut() {
                let w = (luminance(s.le) / s.pdf) as f64;
                r[i][1] += w;
                if visible {
                    r[i][0] += w;
                }
            }
            if contributes && visible {
                let w = self.light_sample_weight(e, &s, brdf_pdf, &at.vertex);
                sum += f * s.le * (wi.z * w / s.pdf);
            }
        }
        if !self.env.is_black() {
            let u = rng.uniform2();
            let sample = if self.portals.is_empty() {
                self.env.sample(u)
            } else {
                // The even mixture's density, whichever half drew the direction.
                let drawn = if rng.uniform() < 0.5 {
                    let pick = rng.uniform();
                    self.portals
                        .sample_direction(p, pick, u)
                        .map(|wi| (wi, self.env.radiance(wi)))
                } else {
                    self.env.sample(u).map(|(wi, le, _)| (wi, le))
                };
                drawn.map(|(wi, le)| (wi, le, self.env_pdf(p, wi)))
            };
            if let Some((wi_world, le, pdf)) = sample {
                let wi = at.frame.to_local(wi_world);
                if pdf > 0.0 && wi_world.dot(ng) > 0.0 && wi.z > 0.0 {
                    let (f, brdf_pdf) = at.brdf.eval(at.wo, wi);
                    if f != Vec3A::ZERO && le != Vec3A::ZERO {
                        counts.shadow += 1;
                        if !self.geometry.occluded(at.origin, wi_world, f32::INFINITY) {
                            sum += f * le * (wi.z * power_heuristic(pdf, brdf_pdf) / pdf);
                        }
                    }
                }
            }
        }
        sum
    }

    /// MIS weight of a light's own sample `s` at `y` against the BRDF's density `brdf_pdf` for
    /// the same direction, and for a directional light with portals also against the beam
    /// strategy at the vertex before `y`.
    fn light_sample_weight(&self, e: &Emitter, s: &LightSample, brdf_pdf: f32, y: &Vertex) -> f32 {
        match e {
            Emitter::Directional { .. } if s.delta => {
                self.distant_weight(DistantPath::BounceThenLight, y, s.wi, 1.0, 0.0)
            }
            Emitter::Directional { .. } => {
                self.distant_weight(DistantPath::BounceThenLight, y, s.wi, s.pdf, brdf_pdf)
            }
            _ if s.delta => 1.0,
            _ => power_heuristic(s.pdf, brdf_pdf),
        }
    }

    /// The beam strategy at a shaded point `x`: for every directional light, a point where its
    /// beam passes a portal, the first surface `y` along the beam from there, and `y`'s reflection
    /// of that light towards `x`, MIS-weighted ([`DistantPath`]).
    fn beam_light(&self, at: &Shading, rng: &mut Rng, counts: &mut RayCounts) -> Vec3A {
        let (x, ng) = (at.vertex.position, at.vertex.geometric_normal);
        let mut sum = Vec3A::ZERO;
        for e in &self.emitters {
            if !matches!(e, Emitter::Directional { .. }) {
                continue;
            }
            let u_light = rng.uniform2();
            let pick = rng.uniform();
            let u_portal = rng.uniform2();
            let Some(s) = e.sample(x, u_light) else {
                continue;
            };
            if s.le == Vec3A::ZERO {
                continue;
            }
            let travel = -s.wi;
            let Some(q) = self.portals.sample_beam(travel, pick, u_portal) else {
                continue;
            };
            counts.shadow += 1;
            if self.geometry.occluded(q, s.wi, f32::INFINITY) {
                continue;
            }
            // Like the light's own shadow rays, the beam passes through emitters.
            counts.closest += 1;
            let Some(hit) = self.geometry.intersect(q, travel, f32::INFINITY) else {
                continue;
            };
            let y = self.geometry.surface_point(q, travel, hit);
            let v = y.position - x;
            let r2 = v.length_squared();
            if !(r2.is_finite() && r2 > 1e-12) {
                continue;
            }
            let r = r2.sqrt();
            let to_y = v / r;
            let cos_y = -to_y.dot(y.geometric_normal);
            if to_y.dot(ng) <= 0.0 || cos_y <= 0.0 {
                continue;
            }
            let wi = at.frame.to_local(to_y);
            if wi.z <= 0.0 {
                continue;
            }
            let (f_x, brdf_pdf_x) = at.brdf.eval(at.wo, wi);
            let material = self.geometry.material(y.object);
            let brdf_y = Brdf::new(
                y.base_color,
                material.metallic,
                material.roughness,
                material.specular,
            );
            let frame_y = Frame::new(y.shading_normal);
            let (wo_y, wi_y) = (frame_y.to_local(-to_y), frame_y.to_local(s.wi));
            if wo_y.z <= 0.0 || wi_y.z <= 0.0 {
                continue;
            }
            let (f_y, brdf_pdf_y) = brdf_y.eval(wo_y, wi_y);
            if f_x == Vec3A::ZERO || f_y == Vec3A::ZERO {
                continue;
            }
            let b = self
                .portals
                .beam_area_pdf(y.position, y.geometric_normal, travel);
            if !(b.is_finite() && b > 0.0) {
                continue;
            }
            let a = brdf_pdf_x * cos_y / r2;
            let (light_pdf, brdf_pdf_y) = if s.delta {
                (1.0, 0.0)
            } else {
                (s.pdf, brdf_pdf_y)
            };
            let w = distant_path_weight(DistantPath::Beam, a, b, light_pdf, brdf_pdf_y);
            if w <= 0.0 {
                continue;
            }
            counts.shadow += 1;
            if self.geometry.occluded(at.origin, to_y, r * (1.0 - 1e-4)) {
                continue;
            }
            sum += f_x * f_y * s.le * (wi.z * wi_y.z * cos_y * w / (s.pdf * r2 * b));
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
                        Emitter::Rect { shape, .. } => shape.normal,
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
