//! Random numbers and the warps from the unit square to directions that the integrator and the
//! lights share.
//!
//! Every sample of every pixel gets its own generator, seeded from (render seed, view, pixel,
//! sample index) alone, so an image does not depend on how pixels are spread over threads.

use glam::{Vec2, Vec3A};
use std::f32::consts::PI;

/// A small, fast generator (PCG32, O'Neill 2014) whose state comes from a hash of the sample's
/// coordinates.
#[derive(Debug, Clone)]
pub(crate) struct Rng {
    state: u64,
    inc: u64,
}

/// SplitMix64 finaliser: a bijective mix so that nearby inputs give unrelated outputs.
fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

impl Rng {
    /// The generator for one (seed, stream, pixel, sample) tuple.
    pub(crate) fn for_sample(seed: u64, stream: u64, pixel: u64, sample: u64) -> Rng {
        let a = mix64(seed ^ mix64(stream.wrapping_add(0x9e37_79b9_7f4a_7c15)));
        let b = mix64(a ^ mix64(pixel.wrapping_mul(0xd6e8_feb8_6659_fd93)));
        let c = mix64(b ^ mix64(sample.wrapping_add(0x2545_f491_4f6c_dd1d)));
        let mut rng = Rng {
            state: 0,
            inc: (mix64(c ^ 0xa076_1d64_78bd_642f) << 1) | 1,
        };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(c);
        rng.next_u32();
        rng
    }

    pub(crate) fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform in [0, 1) (24 bits, so never rounds up to 1.0).
    pub(crate) fn uniform(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }

    pub(crate) fn uniform2(&mut self) -> Vec2 {
        let a = self.uniform();
        let b = self.uniform();
        Vec2::new(a, b)
    }
}

/// An orthonormal basis around `n` (Duff et al. 2017, "Building an Orthonormal Basis, Revisited").
#[derive(Debug, Clone, Copy)]
pub(crate) struct Frame {
    pub t: Vec3A,
    pub b: Vec3A,
    pub n: Vec3A,
}

impl Frame {
    pub(crate) fn new(n: Vec3A) -> Frame {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        Frame {
            t: Vec3A::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
            b: Vec3A::new(b, sign + n.y * n.y * a, -n.y),
            n,
        }
    }
    pub(crate) fn to_local(self, v: Vec3A) -> Vec3A {
        Vec3A::new(v.dot(self.t), v.dot(self.b), v.dot(self.n))
    }
    pub(crate) fn to_world(self, v: Vec3A) -> Vec3A {
        self.t * v.x + self.b * v.y + self.n * v.z
    }
}

/// Cosine-weighted direction on the +Z hemisphere (Malley's method); pdf = z / π.
pub(crate) fn cosine_hemisphere(u: Vec2) -> Vec3A {
    let r = u.x.sqrt();
    let phi = 2.0 * PI * u.y;
    let z = (1.0 - u.x).max(0.0).sqrt();
    Vec3A::new(r * phi.cos(), r * phi.sin(), z)
}

/// Uniform direction in the cone around +Z with `one_minus_cos_max = 1 − cos θmax` (passed in that
/// form because for the sun's 0.27° half-angle `cos θmax` rounds to 1 in f32).
/// pdf = 1 / (2π · one_minus_cos_max).
pub(crate) fn uniform_cone(u: Vec2, one_minus_cos_max: f32) -> Vec3A {
    let h = u.x * one_minus_cos_max; // 1 − cos θ
    let cos_t = 1.0 - h;
    let sin_t = (h * (2.0 - h)).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3A::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t)
}

/// Power heuristic (β = 2) weight of a strategy with density `a` against one with density `b`.
pub(crate) fn power_heuristic(a: f32, b: f32) -> f32 {
    let a2 = a * a;
    let b2 = b * b;
    if a2 + b2 > 0.0 && (a2 + b2).is_finite() {
        a2 / (a2 + b2)
    } else if a.is_infinite() {
        1.0
    } else {
        0.0
    }
}

/// A piecewise-constant 1D distribution over `n` equal cells of [0, 1).
#[derive(Debug, Clone)]
pub(crate) struct Distribution1D {
    cdf: Vec<f32>,
    func: Vec<f32>,
    integral: f32,
    /// The integral of the weights as given (0 when all were zero and the cells were made uniform).
    mass: f32,
}

impl Distribution1D {
    /// From non-negative cell weights; all-zero weights give the uniform distribution.
    pub(crate) fn new(weights: &[f32]) -> Distribution1D {
        let n = weights.len().max(1);
        let mut func: Vec<f32> = weights
            .iter()
            .map(|w| if w.is_finite() && *w > 0.0 { *w } else { 0.0 })
            .collect();
        if func.is_empty() {
            func.push(1.0);
        }
        let mut cdf = Vec::with_capacity(n + 1);
        cdf.push(0.0f32);
        let mut acc = 0.0f64;
        for w in &func {
            acc += *w as f64 / n as f64;
            cdf.push(acc as f32);
        }
        let mut integral = acc as f32;
        let mass = integral;
        if integral <= 0.0 {
            func.iter_mut().for_each(|w| *w = 1.0);
            for (i, c) in cdf.iter_mut().enumerate() {
                *c = i as f32 / n as f32;
            }
            integral = 1.0;
        } else {
            for c in cdf.iter_mut() {
                *c /= integral;
            }
        }
        Distribution1D {
            cdf,
            func,
            integral,
            mass,
        }
    }

    pub(crate) fn len(&self) -> usize {
        self.func.len()
    }

    /// Returns (x in [0,1), density at x, cell index).
    pub(crate) fn sample(&self, u: f32) -> (f32, f32, usize) {
        let n = self.func.len();
        // Last cell whose cdf start is <= u.
        let idx = self
            .cdf
            .partition_point(|c| *c <= u)
            .saturating_sub(1)
            .min(n - 1);
        let width = self.cdf[idx + 1] - self.cdf[idx];
        let du = if width > 0.0 {
            ((u - self.cdf[idx]) / width).clamp(0.0, 1.0)
        } else {
            0.5
        };
        let x = ((idx as f32 + du) / n as f32).min(1.0 - f32::EPSILON);
        (x, self.func[idx] / self.integral, idx)
    }

    /// Density at x in [0, 1).
    pub(crate) fn pdf(&self, x: f32) -> f32 {
        let n = self.func.len();
        let idx = ((x * n as f32) as usize).min(n - 1);
        self.func[idx] / self.integral
    }
}

/// A piecewise-constant 2D distribution over a `width × height` grid of [0,1)².
#[derive(Debug, Clone)]
pub(crate) struct Distribution2D {
    conditional: Vec<Distribution1D>,
    marginal: Distribution1D,
}

impl Distribution2D {
    pub(crate) fn new(weights: &[f32], width: usize, height: usize) -> Distribution2D {
        let conditional: Vec<Distribution1D> = (0..height)
            .map(|y| Distribution1D::new(&weights[y * width..(y + 1) * width]))
            .collect();
        let marginal_weights: Vec<f32> = conditional.iter().map(|c| c.mass).collect();
        Distribution2D {
            conditional,
            marginal: Distribution1D::new(&marginal_weights),
        }
    }

    /// Returns ((x, y) in [0,1)², density with respect to area on [0,1)²).
    pub(crate) fn sample(&self, u: Vec2) -> (Vec2, f32) {
        let (y, pdf_y, row) = self.marginal.sample(u.y);
        let (x, pdf_x, _) = self.conditional[row].sample(u.x);
        (Vec2::new(x, y), pdf_x * pdf_y)
    }

    pub(crate) fn pdf(&self, p: Vec2) -> f32 {
        let h = self.marginal.len();
        let row = ((p.y * h as f32) as usize).min(h - 1);
        self.marginal.pdf(p.y) * self.conditional[row].pdf(p.x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rng_is_uniform_and_depends_on_every_coordinate() {
        let mut r = Rng::for_sample(1, 0, 5, 7);
        let n = 100_000;
        let mean: f64 = (0..n).map(|_| r.uniform() as f64).sum::<f64>() / n as f64;
        assert!((mean - 0.5).abs() < 0.005, "mean {mean}");
        let first = |s, st, p, i| Rng::for_sample(s, st, p, i).next_u32();
        let base = first(1, 0, 5, 7);
        assert_ne!(base, first(2, 0, 5, 7));
        assert_ne!(base, first(1, 1, 5, 7));
        assert_ne!(base, first(1, 0, 6, 7));
        assert_ne!(base, first(1, 0, 5, 8));
    }

    #[test]
    fn distribution_samples_follow_their_weights() {
        let d = Distribution1D::new(&[1.0, 0.0, 3.0]);
        let mut counts = [0usize; 3];
        let mut r = Rng::for_sample(3, 0, 0, 0);
        for _ in 0..40_000 {
            let (x, pdf, idx) = d.sample(r.uniform());
            assert!((0.0..1.0).contains(&x));
            assert!((pdf - d.pdf(x)).abs() < 1e-5);
            counts[idx] += 1;
        }
        assert_eq!(counts[1], 0);
        let ratio = counts[2] as f64 / counts[0] as f64;
        assert!((ratio - 3.0).abs() < 0.15, "ratio {ratio}");
        // Density integrates to one: cells are 1/3 wide.
        assert!(((d.pdf(0.1) + d.pdf(0.5) + d.pdf(0.9)) / 3.0 - 1.0).abs() < 1e-5);
    }

    #[test]
    fn frame_is_orthonormal_for_every_normal() {
        for n in [
            Vec3A::Z,
            -Vec3A::Z,
            Vec3A::X,
            Vec3A::new(0.3, -0.4, 0.866).normalize(),
            Vec3A::new(0.0, 1e-8, -1.0).normalize(),
        ] {
            let f = Frame::new(n);
            assert!(f.t.dot(f.b).abs() < 1e-5 && f.t.dot(n).abs() < 1e-5);
            assert!((f.t.length() - 1.0).abs() < 1e-5 && (f.b.length() - 1.0).abs() < 1e-5);
            let v = Vec3A::new(0.2, 0.5, -0.3);
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-5);
        }
    }
}
