//! Solid procedural textures: value noise, checker, wood-like rings, fine speckle. They give the
//! synthetic walls and tables the texture that stereo matching needs.

use glam::Vec3A;

use super::description::{Pattern, Texture};

/// Size of a speckle cell in metres: fine enough to give every pixel of a 640-pixel view of a room
/// its own value, coarse enough not to alias into noise at that resolution.
const SPECKLE_CELL_M: f32 = 0.004;

const HASH_X: u32 = 0x8da6_b343;
const HASH_Y: u32 = 0xd816_3841;
const HASH_Z: u32 = 0xcb1a_b31f;

/// Finishes a lattice hash (the per-axis products xor-ed together) into [0, 1).
fn finish_hash(mut h: u32) -> f32 {
    h ^= h >> 15;
    h = h.wrapping_mul(0x2c1b_3c6d);
    h ^= h >> 12;
    h = h.wrapping_mul(0x297a_2d39);
    h ^= h >> 15;
    (h >> 8) as f32 / (1u32 << 24) as f32
}

fn hash3(x: i32, y: i32, z: i32) -> f32 {
    finish_hash(
        (x as u32).wrapping_mul(HASH_X)
            ^ (y as u32).wrapping_mul(HASH_Y)
            ^ (z as u32).wrapping_mul(HASH_Z),
    )
}

/// Trilinear value noise in [0, 1] with a smoothstep fade.
pub(crate) fn value_noise(p: Vec3A) -> f32 {
    let f = p.floor();
    let (xi, yi, zi) = (f.x as i32 as u32, f.y as i32 as u32, f.z as i32 as u32);
    let t = p - f;
    let s = t * t * (Vec3A::splat(3.0) - 2.0 * t);
    let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
    // The lattice hash is separable before its finaliser: six products serve all eight corners.
    let hx = [
        xi.wrapping_mul(HASH_X),
        xi.wrapping_add(1).wrapping_mul(HASH_X),
    ];
    let hy = [
        yi.wrapping_mul(HASH_Y),
        yi.wrapping_add(1).wrapping_mul(HASH_Y),
    ];
    let hz = [
        zi.wrapping_mul(HASH_Z),
        zi.wrapping_add(1).wrapping_mul(HASH_Z),
    ];
    let c = |i: usize, j: usize, k: usize| finish_hash(hx[i] ^ hy[j] ^ hz[k]);
    let x0 = lerp(c(0, 0, 0), c(1, 0, 0), s.x);
    let x1 = lerp(c(0, 1, 0), c(1, 1, 0), s.x);
    let x2 = lerp(c(0, 0, 1), c(1, 0, 1), s.x);
    let x3 = lerp(c(0, 1, 1), c(1, 1, 1), s.x);
    lerp(lerp(x0, x1, s.y), lerp(x2, x3, s.y), s.z)
}

/// Fractal sum of `octaves` octaves of value noise, normalised to [0, 1].
pub(crate) fn fbm(p: Vec3A, octaves: u32) -> f32 {
    let (mut sum, mut amp, mut norm, mut q) = (0.0, 1.0, 0.0, p);
    for _ in 0..octaves.max(1) {
        sum += amp * value_noise(q);
        norm += amp;
        amp *= 0.5;
        q = q * 2.03 + Vec3A::splat(17.1);
    }
    sum / norm
}

fn pattern_value(pattern: Pattern, p: Vec3A) -> f32 {
    match pattern {
        Pattern::Checker => {
            let f = p.floor();
            ((f.x as i64 + f.y as i64 + f.z as i64).rem_euclid(2)) as f32
        }
        Pattern::Noise { octaves } => fbm(p, octaves.unwrap_or(4)),
        Pattern::Wood => {
            // Growth rings around an axis parallel to X, 5 cells below the object: on surfaces
            // along X and Z they show as the slightly curved stripes of a plank, wobbled by noise.
            let y = p.y + 5.0;
            let r = (y * y + p.z * p.z).sqrt() + 0.5 * fbm(p * Vec3A::new(0.15, 0.8, 0.8), 3);
            let ring = (r * 4.0).fract();
            let grain = value_noise(p * Vec3A::new(1.0, 30.0, 30.0));
            (ring * ring * 0.8 + 0.2 * grain).clamp(0.0, 1.0)
        }
        Pattern::Speckle => {
            let f = p.floor();
            hash3(f.x as i32, f.y as i32, f.z as i32)
        }
    }
}

/// The base colour of a textured material at object-space point `p` (metres).
pub(crate) fn evaluate(texture: &Texture, base: Vec3A, p: Vec3A) -> Vec3A {
    let t = pattern_value(texture.pattern, p * texture.scale);
    let mut c = base + (Vec3A::from(texture.color) - base) * t;
    if texture.speckle > 0.0 {
        let q = (p / SPECKLE_CELL_M).floor();
        let h = hash3(q.x as i32, q.y as i32, q.z as i32);
        c *= 1.0 + texture.speckle * (2.0 * h - 1.0);
    }
    c.clamp(Vec3A::ZERO, Vec3A::ONE)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_is_continuous_bounded_and_varied() {
        let mut min: f32 = 1.0;
        let mut max: f32 = 0.0;
        for i in 0..2000 {
            let p = Vec3A::new(i as f32 * 0.173, i as f32 * 0.071 - 3.0, 0.5);
            let v = fbm(p, 4);
            assert!((0.0..=1.0).contains(&v));
            min = min.min(v);
            max = max.max(v);
            let dv = (value_noise(p + Vec3A::splat(1e-3)) - value_noise(p)).abs();
            assert!(dv < 0.01, "noise jumps by {dv}");
        }
        assert!(max - min > 0.4, "noise range {min}..{max}");
    }

    #[test]
    fn checker_alternates_and_colours_mix() {
        let t = Texture {
            pattern: Pattern::Checker,
            scale: 2.0,
            color: [0.0; 3],
            speckle: 0.0,
        };
        let white = Vec3A::ONE;
        let a = evaluate(&t, white, Vec3A::new(0.1, 0.1, 0.1));
        let b = evaluate(&t, white, Vec3A::new(0.6, 0.1, 0.1));
        assert_eq!(a, white);
        assert_eq!(b, Vec3A::ZERO);
    }
}
