//! Emitters for next-event estimation: rectangular and spherical area lights, directional lights
//! with an angular diameter, and the environment (constant, sky gradient or equirectangular map),
//! each with a sampling routine and the matching solid-angle density for multiple importance
//! sampling.

use glam::{Vec2, Vec3A};
use std::f32::consts::PI;

use super::description::{Environment, Light};
use super::sampling::{uniform_cone, Distribution2D, Frame};
use crate::error::Result;
use crate::image::{ImageLimits, Raster};

/// A light sample seen from a surface point.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LightSample {
    /// Unit direction from the point towards the light.
    pub wi: Vec3A,
    /// Distance to the sampled point (infinity for distant lights).
    pub dist: f32,
    /// Radiance arriving along `wi` (for a delta light: irradiance).
    pub le: Vec3A,
    /// Density of `wi` per solid angle (1 for a delta light).
    pub pdf: f32,
    /// A delta light cannot be hit by BSDF sampling.
    pub delta: bool,
}

/// The parallelogram `corner + u·eu + v·ev`, u, v ∈ [0, 1], of a rect light or a portal.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Parallelogram {
    pub corner: Vec3A,
    pub eu: Vec3A,
    pub ev: Vec3A,
    /// Unit normal along `eu × ev`.
    pub normal: Vec3A,
    pub area: f32,
}

impl Parallelogram {
    /// The parallelogram with corners `center ± edge_u/2 ± edge_v/2` (of positive area).
    pub(crate) fn centred(center: [f32; 3], edge_u: [f32; 3], edge_v: [f32; 3]) -> Parallelogram {
        let (eu, ev) = (Vec3A::from(edge_u), Vec3A::from(edge_v));
        let cross = eu.cross(ev);
        Parallelogram {
            corner: Vec3A::from(center) - 0.5 * eu - 0.5 * ev,
            eu,
            ev,
            normal: cross.normalize(),
            area: cross.length(),
        }
    }

    /// The point at parameters `u` ∈ [0, 1]².
    pub(crate) fn point(&self, u: Vec2) -> Vec3A {
        self.corner + self.eu * u.x + self.ev * u.y
    }

    /// Ray parameter at which `o + t·d` passes through the parallelogram, from either side, if
    /// it does at `t` in (0, tmax).
    pub(crate) fn crossing(&self, o: Vec3A, d: Vec3A, tmax: f32) -> Option<f32> {
        let denom = d.dot(self.normal);
        if denom.abs() < 1e-12 {
            return None;
        }
        let t = (self.corner - o).dot(self.normal) / denom;
        if !(t > 0.0 && t < tmax) {
            return None;
        }
        let q = o + d * t - self.corner;
        let (eu, ev) = (self.eu, self.ev);
        let (uu, uv, vv) = (eu.dot(eu), eu.dot(ev), ev.dot(ev));
        let (qu, qv) = (q.dot(eu), q.dot(ev));
        let det = uu * vv - uv * uv;
        let a = (qu * vv - qv * uv) / det;
        let b = (qv * uu - qu * uv) / det;
        ((0.0..=1.0).contains(&a) && (0.0..=1.0).contains(&b)).then_some(t)
    }
}

/// One light in world space, ready to sample.
#[derive(Debug, Clone)]
pub(crate) enum Emitter {
    Rect {
        shape: Parallelogram,
        radiance: Vec3A,
    },
    Sphere {
        center: Vec3A,
        radius: f32,
        radiance: Vec3A,
    },
    Directional {
        to_light: Vec3A,
        frame: Frame,
        /// 1 − cos(half angle); 0 for a delta light.
        one_minus_cos: f32,
        /// Radiance inside the cone, or the irradiance of a delta light.
        value: Vec3A,
    },
}

impl Emitter {
    pub(crate) fn new(light: &Light) -> Emitter {
        match light {
            Light::Rect {
                center,
                edge_u,
                edge_v,
                radiance,
            } => Emitter::Rect {
                shape: Parallelogram::centred(*center, *edge_u, *edge_v),
                radiance: Vec3A::from(*radiance),
            },
            Light::Sphere {
                center,
                radius,
                radiance,
            } => Emitter::Sphere {
                center: Vec3A::from(*center),
                radius: *radius,
                radiance: Vec3A::from(*radiance),
            },
            Light::Directional {
                direction,
                irradiance,
                angular_diameter_deg,
            } => {
                let to_light = -Vec3A::from(*direction).normalize();
                let half = (angular_diameter_deg * 0.5).to_radians();
                let e = Vec3A::from(*irradiance);
                let (one_minus_cos, value) = if half > 0.0 {
                    // E = L·π·sin²(half) for a uniform disc of directions.
                    let s = half.sin();
                    (2.0 * (half * 0.5).sin().powi(2), e / (PI * s * s))
                } else {
                    (0.0, e)
                };
                Emitter::Directional {
                    to_light,
                    frame: Frame::new(to_light),
                    one_minus_cos,
                    value,
                }
            }
        }
    }

    /// A sample of this light seen from `p`, or None when the light cannot reach `p` (behind a
    /// one-sided rect, `p` inside a sphere light).
    pub(crate) fn sample(&self, p: Vec3A, u: Vec2) -> Option<LightSample> {
        match self {
            Emitter::Rect { shape, radiance } => {
                let q = shape.point(u);
                let v = q - p;
                let d2 = v.length_squared();
                if d2 <= 0.0 {
                    return None;
                }
                let dist = d2.sqrt();
                let wi = v / dist;
                let cos_l = -wi.dot(shape.normal);
                if cos_l <= 1e-7 {
                    return None;
                }
                Some(LightSample {
                    wi,
                    dist,
                    le: *radiance,
                    pdf: d2 / (shape.area * cos_l),
                    delta: false,
                })
            }
            Emitter::Sphere {
                center,
                radius,
                radiance,
            } => {
                let axis = *center - p;
                let d2 = axis.length_squared();
                let r2 = radius * radius;
                if d2 <= r2 * 1.0001 {
                    return None;
                }
                let sin2 = r2 / d2;
                let one_minus_cos = sin2 / (1.0 + (1.0 - sin2).sqrt());
                let d = d2.sqrt();
                let frame = Frame::new(axis / d);
                let wi = frame.to_world(uniform_cone(u, one_minus_cos));
                // Nearest intersection of the sampled ray with the sphere.
                let b = wi.dot(axis);
                let disc = (r2 - (d2 - b * b)).max(0.0);
                let dist = (b - disc.sqrt()).max(0.0);
                Some(LightSample {
                    wi,
                    dist,
                    le: *radiance,
                    pdf: 1.0 / (2.0 * PI * one_minus_cos),
                    delta: false,
                })
            }
            Emitter::Directional {
                to_light,
                frame,
                one_minus_cos,
                value,
            } => {
                if *one_minus_cos == 0.0 {
                    Some(LightSample {
                        wi: *to_light,
                        dist: f32::INFINITY,
                        le: *value,
                        pdf: 1.0,
                        delta: true,
                    })
                } else {
                    Some(LightSample {
                        wi: frame.to_world(uniform_cone(u, *one_minus_cos)),
                        dist: f32::INFINITY,
                        le: *value,
                        pdf: 1.0 / (2.0 * PI * one_minus_cos),
                        delta: false,
                    })
                }
            }
        }
    }

    /// Ray parameter of the nearest hit of this light within (0, tmax), for rect and sphere lights.
    pub(crate) fn intersect(&self, o: Vec3A, d: Vec3A, tmax: f32) -> Option<f32> {
        match self {
            Emitter::Rect { shape, .. } => shape.crossing(o, d, tmax),
            Emitter::Sphere { center, radius, .. } => {
                let oc = o - *center;
                let b = oc.dot(d);
                let c = oc.length_squared() - radius * radius;
                let disc = b * b - c;
                if disc < 0.0 {
                    return None;
                }
                let s = disc.sqrt();
                let t = if -b - s > 0.0 { -b - s } else { -b + s };
                (t > 0.0 && t < tmax).then_some(t)
            }
            Emitter::Directional { .. } => None,
        }
    }

    /// Radiance leaving the light towards the ray that hit it (`d` = ray direction), and the
    /// density with which `sample` from `p` would have produced this direction.
    pub(crate) fn hit(&self, p: Vec3A, d: Vec3A, t: f32) -> (Vec3A, f32) {
        match self {
            Emitter::Rect { shape, radiance } => {
                let cos_l = -d.dot(shape.normal);
                if cos_l <= 1e-7 {
                    (Vec3A::ZERO, 0.0)
                } else {
                    (*radiance, t * t / (shape.area * cos_l))
                }
            }
            Emitter::Sphere {
                center,
                radius,
                radiance,
            } => {
                let d2 = (*center - p).length_squared();
                let r2 = radius * radius;
                if d2 <= r2 * 1.0001 {
                    return (*radiance, 0.0);
                }
                let sin2 = r2 / d2;
                let one_minus_cos = sin2 / (1.0 + (1.0 - sin2).sqrt());
                (*radiance, 1.0 / (2.0 * PI * one_minus_cos))
            }
            Emitter::Directional { .. } => (Vec3A::ZERO, 0.0),
        }
    }

    /// For a ray escaping to infinity along `d`: the radiance of a directional light with an
    /// angular size in that direction, and its sampling density.
    pub(crate) fn escaped(&self, d: Vec3A) -> Option<(Vec3A, f32)> {
        match self {
            Emitter::Directional {
                to_light,
                one_minus_cos,
                value,
                ..
            } if *one_minus_cos > 0.0 && 1.0 - d.dot(*to_light) <= *one_minus_cos => {
                Some((*value, 1.0 / (2.0 * PI * one_minus_cos)))
            }
            _ => None,
        }
    }
}

/// How the environment's radiance is defined.
#[derive(Debug, Clone)]
enum EnvRadiance {
    Black,
    Constant(Vec3A),
    Sky {
        zenith: Vec3A,
        horizon: Vec3A,
        ground: Vec3A,
    },
    Map {
        pixels: Raster<[f32; 3]>,
        scale: f32,
        rotation: f32,
    },
}

/// The environment as a light: radiance per direction and an importance-sampling distribution
/// over the equirectangular domain.
#[derive(Debug, Clone)]
pub(crate) struct EnvLight {
    radiance: EnvRadiance,
    distribution: Distribution2D,
}

/// Resolution of the sampling grid for analytic environments.
const ANALYTIC_GRID: (usize, usize) = (64, 32);

fn luminance(c: Vec3A) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// Equirectangular coordinates in [0,1)² of a unit direction: the centre column looks along −Z,
/// u = 0.75 along +X, the top row (v = 0) is +Y.
pub(crate) fn direction_to_equirect(d: Vec3A) -> Vec2 {
    let phi = d.x.atan2(-d.z);
    let u = 0.5 + phi / (2.0 * PI);
    let v = d.y.clamp(-1.0, 1.0).acos() / PI;
    Vec2::new(u.rem_euclid(1.0), v.clamp(0.0, 1.0 - f32::EPSILON))
}

/// Inverse of [`direction_to_equirect`].
pub(crate) fn equirect_to_direction(uv: Vec2) -> Vec3A {
    let phi = (uv.x - 0.5) * 2.0 * PI;
    let theta = uv.y * PI;
    Vec3A::new(
        theta.sin() * phi.sin(),
        theta.cos(),
        -theta.sin() * phi.cos(),
    )
}

fn rotate_y(d: Vec3A, angle: f32) -> Vec3A {
    let (s, c) = angle.sin_cos();
    Vec3A::new(c * d.x + s * d.z, d.y, -s * d.x + c * d.z)
}

impl EnvLight {
    /// Builds the environment; reads the file of an `Equirect` environment.
    ///
    /// # Errors
    /// `Io`/`Format` when the map cannot be read, `TooLarge` over the default image cap.
    pub(crate) fn new(env: &Environment) -> Result<EnvLight> {
        let radiance = match env {
            Environment::Black => EnvRadiance::Black,
            Environment::Constant { radiance } => EnvRadiance::Constant(Vec3A::from(*radiance)),
            Environment::Sky {
                zenith,
                horizon,
                ground,
            } => EnvRadiance::Sky {
                zenith: Vec3A::from(*zenith),
                horizon: Vec3A::from(*horizon),
                ground: Vec3A::from(*ground),
            },
            Environment::Equirect {
                path,
                scale,
                rotation_deg,
            } => EnvRadiance::Map {
                pixels: Raster::read_hdr(path, &ImageLimits::default())?,
                scale: *scale,
                rotation: rotation_deg.to_radians(),
            },
        };
        let (width, height) = match &radiance {
            EnvRadiance::Map { pixels, .. } => (pixels.width(), pixels.height()),
            _ => ANALYTIC_GRID,
        };
        let mut env = EnvLight {
            radiance,
            distribution: Distribution2D::new(&[1.0], 1, 1),
        };
        let mut weights = Vec::with_capacity(width * height);
        for y in 0..height {
            let v = (y as f32 + 0.5) / height as f32;
            let sin_theta = (v * PI).sin();
            for x in 0..width {
                let u = (x as f32 + 0.5) / width as f32;
                let l = match &env.radiance {
                    EnvRadiance::Map { pixels, scale, .. } => {
                        luminance(Vec3A::from(*pixels.get(x, y))) * scale
                    }
                    _ => luminance(env.eval_local(equirect_to_direction(Vec2::new(u, v)))),
                };
                weights.push(l.max(0.0) * sin_theta);
            }
        }
        env.distribution = Distribution2D::new(&weights, width, height);
        Ok(env)
    }

    /// Whether the environment emits nothing (no need to sample it).
    pub(crate) fn is_black(&self) -> bool {
        match &self.radiance {
            EnvRadiance::Black => true,
            EnvRadiance::Constant(c) => *c == Vec3A::ZERO,
            EnvRadiance::Sky {
                zenith,
                horizon,
                ground,
            } => *zenith == Vec3A::ZERO && *horizon == Vec3A::ZERO && *ground == Vec3A::ZERO,
            EnvRadiance::Map { scale, .. } => *scale == 0.0,
        }
    }

    /// Radiance from direction `d` in the map's own frame (before rotation).
    fn eval_local(&self, d: Vec3A) -> Vec3A {
        match &self.radiance {
            EnvRadiance::Black => Vec3A::ZERO,
            EnvRadiance::Constant(c) => *c,
            EnvRadiance::Sky {
                zenith,
                horizon,
                ground,
            } => {
                if d.y >= 0.0 {
                    *horizon + (*zenith - *horizon) * d.y
                } else {
                    *ground
                }
            }
            EnvRadiance::Map { pixels, scale, .. } => {
                let uv = direction_to_equirect(d);
                let x = ((uv.x * pixels.width() as f32) as usize).min(pixels.width() - 1);
                let y = ((uv.y * pixels.height() as f32) as usize).min(pixels.height() - 1);
                Vec3A::from(*pixels.get(x, y)) * *scale
            }
        }
    }

    fn rotation(&self) -> f32 {
        match &self.radiance {
            EnvRadiance::Map { rotation, .. } => *rotation,
            _ => 0.0,
        }
    }

    /// Radiance arriving from world direction `d` (unit).
    pub(crate) fn radiance(&self, d: Vec3A) -> Vec3A {
        self.eval_local(rotate_y(d, -self.rotation()))
    }

    /// Samples a world direction: (direction, radiance, density per solid angle).
    pub(crate) fn sample(&self, u: Vec2) -> Option<(Vec3A, Vec3A, f32)> {
        let (uv, pdf_uv) = self.distribution.sample(u);
        let sin_theta = (uv.y * PI).sin();
        if pdf_uv <= 0.0 || sin_theta <= 0.0 {
            return None;
        }
        let local = equirect_to_direction(uv);
        let pdf = pdf_uv / (2.0 * PI * PI * sin_theta);
        Some((
            rotate_y(local, self.rotation()),
            self.eval_local(local),
            pdf,
        ))
    }

    /// Density per solid angle with which `sample` produces world direction `d`.
    pub(crate) fn pdf(&self, d: Vec3A) -> f32 {
        let local = rotate_y(d, -self.rotation());
        let uv = direction_to_equirect(local);
        let sin_theta = (uv.y * PI).sin();
        if sin_theta <= 0.0 {
            return 0.0;
        }
        self.distribution.pdf(uv) / (2.0 * PI * PI * sin_theta)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::sampling::Rng;

    #[test]
    fn equirect_mapping_round_trips_and_follows_the_convention() {
        for d in [
            Vec3A::new(0.3, 0.5, -0.8).normalize(),
            Vec3A::new(-0.9, -0.1, 0.2).normalize(),
        ] {
            let back = equirect_to_direction(direction_to_equirect(d));
            assert!((back - d).length() < 1e-5);
        }
        assert!((direction_to_equirect(-Vec3A::Z) - Vec2::new(0.5, 0.5)).length() < 1e-6);
        assert!((direction_to_equirect(Vec3A::X).x - 0.75).abs() < 1e-6);
        assert!(direction_to_equirect(Vec3A::Y).y < 1e-6);
    }

    /// The estimator E[L cos / pdf] over sampled directions must give the analytic irradiance.
    #[test]
    fn environment_sampling_is_unbiased() {
        let sky = EnvLight::new(&Environment::Sky {
            zenith: [2.0; 3],
            horizon: [0.5; 3],
            ground: [0.1; 3],
        })
        .unwrap();
        // Irradiance on an upward-facing plane: ∫ (h + (z−h) cosθ) cosθ dω = π h + 2π/3 (z − h).
        let expected = PI * 0.5 + 2.0 * PI / 3.0 * 1.5;
        let mut rng = Rng::for_sample(5, 0, 0, 0);
        let n = 200_000;
        let mut sum = 0.0f64;
        let mut mismatches = 0;
        for _ in 0..n {
            if let Some((d, l, pdf)) = sky.sample(rng.uniform2()) {
                // Only samples on a cell boundary may find the neighbouring cell's density.
                if (sky.pdf(d) / pdf - 1.0).abs() > 1e-3 {
                    mismatches += 1;
                }
                if d.y > 0.0 {
                    sum += (l.y * d.y / pdf) as f64;
                }
            }
        }
        let e = sum / n as f64;
        assert!(
            (e / expected as f64 - 1.0).abs() < 0.01,
            "{e} vs {expected}"
        );
        assert!(
            mismatches < n / 1000,
            "{mismatches} samples with another density"
        );
    }

    #[test]
    fn sphere_light_sampling_gives_point_irradiance() {
        // A sphere of radius R and radiance L at distance d straight above: E = π L R²/d².
        let light = Emitter::new(&Light::Sphere {
            center: [0.0, 2.0, 0.0],
            radius: 0.1,
            radiance: [10.0; 3],
        });
        let mut rng = Rng::for_sample(6, 0, 0, 0);
        let n = 20_000;
        let mut sum = 0.0f64;
        for _ in 0..n {
            let s = light.sample(Vec3A::ZERO, rng.uniform2()).unwrap();
            sum += (s.le.x * s.wi.y / s.pdf) as f64;
            let t = light.intersect(Vec3A::ZERO, s.wi, 10.0).unwrap();
            assert!((t - s.dist).abs() < 1e-4);
            assert!((light.hit(Vec3A::ZERO, s.wi, t).1 / s.pdf - 1.0).abs() < 1e-4);
        }
        let expected = PI * 10.0 * 0.01 / 4.0;
        assert!(((sum / n as f64) / expected as f64 - 1.0).abs() < 2e-3);
    }

    #[test]
    fn rect_light_pdf_matches_hit_density() {
        let light = Emitter::new(&Light::Rect {
            center: [0.0, 2.0, 0.0],
            edge_u: [1.0, 0.0, 0.0],
            edge_v: [0.0, 0.0, 0.5],
            radiance: [1.0; 3],
        });
        // edge_u × edge_v = X × Z·0.5 = −Y: emits downwards.
        let mut rng = Rng::for_sample(8, 0, 0, 0);
        let p = Vec3A::new(0.3, 0.0, 0.1);
        for _ in 0..100 {
            let s = light.sample(p, rng.uniform2()).unwrap();
            let t = light.intersect(p, s.wi, 100.0).unwrap();
            assert!((t - s.dist).abs() < 1e-4);
            let (le, pdf) = light.hit(p, s.wi, t);
            assert_eq!(le, Vec3A::ONE);
            assert!((pdf / s.pdf - 1.0).abs() < 1e-3);
        }
        assert!(light
            .sample(Vec3A::new(0.0, 3.0, 0.0), Vec2::splat(0.5))
            .is_none());
    }
}
