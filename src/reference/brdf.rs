//! The glTF 2.0 metallic-roughness BRDF (glTF 2.0 specification, Appendix B): Lambert diffuse,
//! the GGX (Trowbridge-Reitz) microfacet distribution, the height-correlated Smith visibility
//! term and Schlick's Fresnel, mixed as the spec writes it:
//!
//! ```text
//! dielectric = mix(diffuse, specular, k · (0.04 + 0.96 (1 − V·H)^5))
//! metal      = specular · (base + (1 − base)(1 − V·H)^5)
//! f          = mix(dielectric, metal, metallic)
//! ```
//!
//! Importance sampling picks between a cosine-weighted lobe and the distribution of visible
//! normals (Heitz 2018, "Sampling the GGX Distribution of Visible Normals"); the returned density is
//! that of the mixture, so it can be used for multiple importance sampling.
//!
//! `k` is the `specular` factor of KHR_materials_specular (f0 = 0.04·k, f90 = k): 1 is plain glTF,
//! 0 a pure Lambertian surface.
//!
//! Vectors are in the shading frame: the normal is +Z and `wo` (towards the viewer) has `z > 0`.

use glam::Vec3A;
use std::f32::consts::{FRAC_1_PI, PI};

/// The smallest α (= roughness²) used: a roughness-0 surface becomes a very sharp GGX lobe, so that
/// every surface can be sampled by both strategies. α = 10⁻³ is sharper than a pixel at any
/// resolution this renderer is used at.
pub(crate) const MIN_ALPHA: f32 = 1e-3;

/// A material at one surface point.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Brdf {
    pub base: Vec3A,
    pub metallic: f32,
    pub alpha: f32,
    /// KHR_materials_specular factor of the dielectric layer.
    pub specular: f32,
}

fn luminance(c: Vec3A) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

impl Brdf {
    pub(crate) fn new(base: Vec3A, metallic: f32, roughness: f32, specular: f32) -> Brdf {
        Brdf {
            base,
            metallic: metallic.clamp(0.0, 1.0),
            alpha: (roughness * roughness).max(MIN_ALPHA),
            specular: specular.clamp(0.0, 1.0),
        }
    }

    /// GGX normal distribution D(h) for a unit half vector in the shading frame.
    fn distribution(&self, h: Vec3A) -> f32 {
        let a2 = self.alpha * self.alpha;
        // (N·H)²(α² − 1) + 1 written as α²(N·H)² + (1 − (N·H)²), with 1 − (N·H)² taken from the
        // tangential components: exact even when α² is far below f32's resolution near 1.
        let d = a2 * h.z * h.z + (h.x * h.x + h.y * h.y);
        if h.z <= 0.0 || d <= 0.0 {
            return 0.0;
        }
        a2 * FRAC_1_PI / (d * d)
    }

    /// Height-correlated Smith visibility V = G / (4 |N·L| |N·V|).
    fn visibility(&self, nl: f32, nv: f32) -> f32 {
        let a2 = self.alpha * self.alpha;
        let gv = nl * (nv * nv * (1.0 - a2) + a2).sqrt();
        let gl = nv * (nl * nl * (1.0 - a2) + a2).sqrt();
        let s = gv + gl;
        if s > 0.0 {
            0.5 / s
        } else {
            0.0
        }
    }

    /// Smith G1 of the viewing direction (used by the visible-normal density).
    fn g1(&self, nv: f32) -> f32 {
        let a2 = self.alpha * self.alpha;
        2.0 * nv / (nv + (a2 + (1.0 - a2) * nv * nv).sqrt())
    }

    /// Probability of sampling the specular lobe, from the Fresnel weights at normal·view.
    fn specular_probability(&self, wo: Vec3A) -> f32 {
        let s = (1.0 - wo.z.clamp(0.0, 1.0)).powi(5);
        let f_diel = self.specular * (0.04 + 0.96 * s);
        let f_metal = self.base + (Vec3A::ONE - self.base) * s;
        let spec = (1.0 - self.metallic) * f_diel + self.metallic * luminance(f_metal);
        let diff = (1.0 - self.metallic) * (1.0 - f_diel) * luminance(self.base);
        if spec + diff > 0.0 {
            (spec / (spec + diff)).clamp(0.0, 1.0)
        } else {
            0.5
        }
    }

    /// The BRDF value (without the cosine) and the sampling density of `wi` (solid angle).
    pub(crate) fn eval(&self, wo: Vec3A, wi: Vec3A) -> (Vec3A, f32) {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return (Vec3A::ZERO, 0.0);
        }
        let h = (wo + wi).normalize_or_zero();
        if h == Vec3A::ZERO {
            return (Vec3A::ZERO, 0.0);
        }
        let vh = wo.dot(h).clamp(0.0, 1.0);
        let s = (1.0 - vh).powi(5);
        let d = self.distribution(h);
        let specular = d * self.visibility(wi.z, wo.z);
        let f_diel = self.specular * (0.04 + 0.96 * s);
        let f_metal = self.base + (Vec3A::ONE - self.base) * s;
        let dielectric = self.base * (FRAC_1_PI * (1.0 - f_diel)) + Vec3A::splat(f_diel * specular);
        let metal = f_metal * specular;
        let f = dielectric * (1.0 - self.metallic) + metal * self.metallic;

        let p_spec = self.specular_probability(wo);
        let pdf_spec = self.g1(wo.z) * d / (4.0 * wo.z);
        let pdf_diff = wi.z * FRAC_1_PI;
        (f, p_spec * pdf_spec + (1.0 - p_spec) * pdf_diff)
    }

    /// Samples an incoming direction; returns (wi, f, pdf) or None when the sample leaves the
    /// upper hemisphere or carries no weight.
    pub(crate) fn sample(
        &self,
        wo: Vec3A,
        u_lobe: f32,
        u: glam::Vec2,
    ) -> Option<(Vec3A, Vec3A, f32)> {
        if wo.z <= 0.0 {
            return None;
        }
        let wi = if u_lobe < self.specular_probability(wo) {
            let h = self.sample_visible_normal(wo, u);
            2.0 * wo.dot(h) * h - wo
        } else {
            super::sampling::cosine_hemisphere(u)
        };
        if wi.z <= 0.0 {
            return None;
        }
        let (f, pdf) = self.eval(wo, wi);
        if pdf > 0.0 && pdf.is_finite() && f.is_finite() {
            Some((wi, f, pdf))
        } else {
            None
        }
    }

    /// Heitz (2018): a microfacet normal drawn from the GGX distribution of visible normals.
    fn sample_visible_normal(&self, wo: Vec3A, u: glam::Vec2) -> Vec3A {
        let a = self.alpha;
        let vh = Vec3A::new(a * wo.x, a * wo.y, wo.z).normalize();
        let lensq = vh.x * vh.x + vh.y * vh.y;
        let t1 = if lensq > 0.0 {
            Vec3A::new(-vh.y, vh.x, 0.0) / lensq.sqrt()
        } else {
            Vec3A::X
        };
        let t2 = vh.cross(t1);
        let r = u.x.sqrt();
        let phi = 2.0 * PI * u.y;
        let p1 = r * phi.cos();
        let mut p2 = r * phi.sin();
        let s = 0.5 * (1.0 + vh.z);
        p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * p2;
        let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * vh;
        Vec3A::new(a * nh.x, a * nh.y, nh.z.max(0.0)).normalize()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::sampling::Rng;

    fn dir(theta_deg: f32, phi_deg: f32) -> Vec3A {
        let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
        Vec3A::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
    }

    /// ∫ f cos dω estimated two ways: by uniform hemisphere sampling and by the BRDF's own
    /// sampler (f cos / pdf). They agree only when `sample` and `eval`'s pdf are consistent.
    fn albedo_two_ways(b: &Brdf, wo: Vec3A, n: usize) -> (f32, f32) {
        let mut rng = Rng::for_sample(7, 0, 0, 0);
        let mut uniform = 0.0f64;
        let mut sampled = 0.0f64;
        for _ in 0..n {
            let u = rng.uniform2();
            let z = u.x;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = 2.0 * PI * u.y;
            let wi = Vec3A::new(r * phi.cos(), r * phi.sin(), z);
            uniform += (b.eval(wo, wi).0.y * wi.z * 2.0 * PI) as f64;
            let lobe = rng.uniform();
            if let Some((wi, f, pdf)) = b.sample(wo, lobe, rng.uniform2()) {
                sampled += (f.y * wi.z / pdf) as f64;
            }
        }
        ((uniform / n as f64) as f32, (sampled / n as f64) as f32)
    }

    #[test]
    fn pure_lambert_reflects_everything() {
        let b = Brdf::new(Vec3A::ONE, 0.0, 0.3, 0.0);
        let (u, s) = albedo_two_ways(&b, dir(60.0, 0.0), 100_000);
        assert!((u - 1.0).abs() < 0.01 && (s - 1.0).abs() < 1e-4, "{u} {s}");
    }

    #[test]
    fn white_rough_dielectric_reflects_nearly_everything() {
        let b = Brdf::new(Vec3A::ONE, 0.0, 1.0, 1.0);
        // Pure Lambert part: f = (1 − F)/π + F·spec; the total is close to 1 for a rough white
        // dielectric (single-scattering GGX loses a few percent at roughness 1).
        let (u, s) = albedo_two_ways(&b, dir(30.0, 0.0), 200_000);
        assert!((u - s).abs() < 0.01, "uniform {u} vs sampled {s}");
        assert!(u > 0.9 && u < 1.01, "albedo {u}");
    }

    #[test]
    fn sampling_density_matches_evaluation_for_glossy_and_metal() {
        for (metallic, roughness) in [(0.0, 0.5), (1.0, 0.3), (1.0, 0.8), (0.5, 0.6)] {
            let b = Brdf::new(Vec3A::new(0.9, 0.6, 0.3), metallic, roughness, 1.0);
            for theta in [0.0, 45.0, 80.0] {
                let (u, s) = albedo_two_ways(&b, dir(theta, 20.0), 400_000);
                assert!(
                    (u - s).abs() < 0.02 * u.max(0.1),
                    "m={metallic} r={roughness} θ={theta}: uniform {u} vs sampled {s}"
                );
                assert!(u <= 1.0 + 0.02, "energy gain {u}");
            }
        }
    }

    #[test]
    fn ggx_distribution_is_normalised() {
        // ∫ D(h) (n·h) dω_h = 1 over the hemisphere.
        for roughness in [0.4f32, 0.6, 1.0] {
            let b = Brdf::new(Vec3A::ONE, 1.0, roughness, 1.0);
            let n = 400_000;
            let mut rng = Rng::for_sample(9, 0, 0, 0);
            let mut sum = 0.0f64;
            for _ in 0..n {
                let u = rng.uniform2();
                let h = super::super::sampling::cosine_hemisphere(u);
                // pdf = cos/π, so D cos / pdf = D π.
                sum += (b.distribution(h) * PI) as f64;
            }
            let integral = sum / n as f64;
            assert!((integral - 1.0).abs() < 0.03, "r={roughness}: {integral}");
        }
    }

    #[test]
    fn mirror_limit_is_finite() {
        let b = Brdf::new(Vec3A::ONE, 1.0, 0.0, 1.0);
        let wo = dir(30.0, 0.0);
        let (wi, f, pdf) = b.sample(wo, 0.0, glam::Vec2::new(0.3, 0.7)).unwrap();
        assert!(f.is_finite() && pdf.is_finite() && pdf > 0.0);
        // Nearly the mirror direction.
        assert!((wi - Vec3A::new(-wo.x, -wo.y, wo.z)).length() < 0.01);
    }
}
