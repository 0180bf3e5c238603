//! Split-sum image-based lighting on the CPU (Karis 2013; Filament's layout): the GGX-prefiltered
//! mip chain of an environment cube, the DFG lookup table, and the thesis' roughness
//! approximation (Algorithm 3) for materials without a roughness value.

use glam::Vec3;
use rayon::prelude::*;

use super::model::{cube_direction, cube_texel, CubeLevel, CubeMap, CUBE_FACES};
use crate::error::{Error, Result};

/// Largest face size accepted, texels (a CPU prefilter of more is far too slow to be useful).
pub const MAX_PREFILTER_SIZE: u32 = 1024;

/// The `i`-th of `n` points of the Hammersley set on [0, 1)².
fn hammersley(i: u32, n: u32) -> (f32, f32) {
    (
        i as f32 / n as f32,
        i.reverse_bits() as f32 * 2.328_306_4e-10,
    )
}

/// A GGX half vector around +Z for `α` (= perceptual roughness²) from a uniform point.
fn ggx_half(alpha: f32, u: (f32, f32)) -> Vec3 {
    let a2 = alpha * alpha;
    let phi = 2.0 * std::f32::consts::PI * u.0;
    let cos_t = ((1.0 - u.1) / (1.0 + (a2 - 1.0) * u.1)).max(0.0).sqrt();
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t)
}

/// GGX normal distribution D(n·h) for `α`.
fn ggx_d(alpha: f32, n_dot_h: f32) -> f32 {
    let a2 = alpha * alpha;
    let d = n_dot_h * n_dot_h * (a2 - 1.0) + 1.0;
    a2 / (std::f32::consts::PI * d * d)
}

fn basis(n: Vec3) -> (Vec3, Vec3) {
    let t = if n.z.abs() < 0.999 { Vec3::Z } else { Vec3::X };
    let x = t.cross(n).normalize();
    (x, n.cross(x))
}

/// Radiance of a cube level in direction `d` (nearest texel); black for a level whose texel count
/// does not match its size.
pub fn sample_cube(level: &CubeLevel, d: Vec3) -> [f32; 3] {
    let (face, s, t) = cube_texel(d);
    let n = level.size as usize;
    if n == 0 || level.texels.len() != CUBE_FACES * n * n {
        return [0.0; 3];
    }
    let i = ((s * n as f32) as usize).min(n - 1);
    let j = ((t * n as f32) as usize).min(n - 1);
    level.texels[face * n * n + j * n + i]
}

fn check_level(level: &CubeLevel) -> Result<()> {
    let n = level.size as usize;
    if level.size == 0 || level.size > MAX_PREFILTER_SIZE {
        return Err(Error::invalid(format!(
            "cube face size must be in 1..={MAX_PREFILTER_SIZE}, got {}",
            level.size
        )));
    }
    if level.texels.len() != CUBE_FACES * n * n {
        return Err(Error::SizeMismatch(format!(
            "cube level of size {n} needs {} texels, got {}",
            CUBE_FACES * n * n,
            level.texels.len()
        )));
    }
    if let Some(bad) = level
        .texels
        .iter()
        .find(|t| t.iter().any(|v| !v.is_finite()))
    {
        return Err(Error::invalid(format!(
            "cube texels must be finite, got {bad:?}"
        )));
    }
    Ok(())
}

/// Halves a level by 2×2 averaging (odd sizes round down, at least 1).
fn downsample(level: &CubeLevel) -> CubeLevel {
    let n = level.size as usize;
    let m = (n / 2).max(1);
    let mut texels = Vec::with_capacity(CUBE_FACES * m * m);
    for f in 0..CUBE_FACES {
        for j in 0..m {
            for i in 0..m {
                let mut acc = [0.0f32; 3];
                let mut count = 0.0;
                for (di, dj) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let (x, y) = ((2 * i + di).min(n - 1), (2 * j + dj).min(n - 1));
                    let t = level.texels[f * n * n + y * n + x];
                    for k in 0..3 {
                        acc[k] += t[k];
                    }
                    count += 1.0;
                }
                texels.push(acc.map(|v| v / count));
            }
        }
    }
    CubeLevel {
        size: m as u32,
        texels,
    }
}

/// GGX-prefiltered mip chain of `base` (level 0 of an environment, linear radiance).
///
/// Level `k` of `levels` holds, for each texel direction `R`, the radiance integral of the split
/// sum with `N = V = R` for perceptual roughness `k / (levels − 1)` (α = roughness²), importance
/// sampled with `samples` GGX samples per texel; each sample reads a box-filtered copy of the
/// source whose texel matches the sample's solid angle (Karis' "filtered importance sampling"),
/// so few samples give little noise. Level `k` has faces of `max(size >> k, 1)` texels; level 0 is
/// `base` itself (a mirror).
///
/// # Errors
/// `InvalidArgument` for a face size outside 1..=[`MAX_PREFILTER_SIZE`], non-finite texels,
/// `levels` outside 1..=16 or `samples` outside 1..=65536; `SizeMismatch` when the texel count
/// does not match the size.
pub fn prefilter_ggx(base: &CubeLevel, levels: usize, samples: u32) -> Result<CubeMap> {
    check_level(base)?;
    if !(1..=16).contains(&levels) {
        return Err(Error::invalid(format!(
            "prefilter levels must be in 1..=16, got {levels}"
        )));
    }
    if !(1..=65536).contains(&samples) {
        return Err(Error::invalid(format!(
            "prefilter samples must be in 1..=65536, got {samples}"
        )));
    }
    let mut pyramid = vec![base.clone()];
    while pyramid.last().is_some_and(|l| l.size > 1) {
        let next = downsample(pyramid.last().unwrap_or(base));
        pyramid.push(next);
    }
    let base_texel_solid_angle = 4.0 * std::f32::consts::PI / (6.0 * (base.size as f32).powi(2));
    let mut out = vec![base.clone()];
    for k in 1..levels {
        let roughness = k as f32 / (levels - 1) as f32;
        let alpha = (roughness * roughness).max(1e-3);
        let n = (base.size as usize >> k).max(1);
        let texels: Vec<[f32; 3]> = (0..CUBE_FACES * n * n)
            .into_par_iter()
            .map(|idx| {
                let (f, j, i) = (idx / (n * n), (idx / n) % n, idx % n);
                let normal =
                    cube_direction(f, (i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                let (tx, ty) = basis(normal);
                let mut acc = [0.0f64; 3];
                let mut weight = 0.0f64;
                for s in 0..samples {
                    let h = ggx_half(alpha, hammersley(s, samples));
                    let h = tx * h.x + ty * h.y + normal * h.z;
                    let v_dot_h = normal.dot(h);
                    let l = 2.0 * v_dot_h * h - normal;
                    let n_dot_l = normal.dot(l);
                    if n_dot_l <= 0.0 {
                        continue;
                    }
                    // pdf of l = D · (n·h) / (4 · v·h) and with v = n, n·h = v·h.
                    let pdf = ggx_d(alpha, v_dot_h) / 4.0;
                    let sample_solid_angle = 1.0 / (samples as f32 * pdf.max(1e-8));
                    let mip = (0.5 * (sample_solid_angle / base_texel_solid_angle).log2() + 1.0)
                        .clamp(0.0, (pyramid.len() - 1) as f32);
                    let c = sample_cube(&pyramid[mip.round() as usize], l);
                    for c_k in 0..3 {
                        acc[c_k] += c[c_k] as f64 * n_dot_l as f64;
                    }
                    weight += n_dot_l as f64;
                }
                if weight > 0.0 {
                    acc.map(|v| (v / weight) as f32)
                } else {
                    sample_cube(base, normal)
                }
            })
            .collect();
        out.push(CubeLevel {
            size: n as u32,
            texels,
        });
    }
    Ok(CubeMap { levels: out })
}

/// The split-sum DFG table (Karis 2013): `size × size` entries `[A, B]`, row `j` for perceptual
/// roughness `(j + 0.5) / size`, column `i` for n·v `(i + 0.5) / size`, stored at `j·size + i`;
/// the specular of a material with reflectance `F0` under a prefiltered radiance `L` is
/// `L · (F0 · A + B)`. Uses the height-correlated Smith-GGX visibility (Filament) and 512
/// Hammersley samples per entry. Every value lies in [0, 1].
///
/// # Errors
/// `InvalidArgument` for a size outside 1..=1024.
pub fn dfg_lut(size: usize) -> Result<Vec<[f32; 2]>> {
    if !(1..=1024).contains(&size) {
        return Err(Error::invalid(format!(
            "DFG table size must be in 1..=1024, got {size}"
        )));
    }
    const SAMPLES: u32 = 512;
    Ok((0..size * size)
        .into_par_iter()
        .map(|idx| {
            let (j, i) = (idx / size, idx % size);
            let roughness = (j as f32 + 0.5) / size as f32;
            let alpha = (roughness * roughness).max(1e-4);
            let n_dot_v = (i as f32 + 0.5) / size as f32;
            let v = Vec3::new((1.0 - n_dot_v * n_dot_v).max(0.0).sqrt(), 0.0, n_dot_v);
            let (mut a, mut b) = (0.0f64, 0.0f64);
            let a2 = alpha * alpha;
            for s in 0..SAMPLES {
                let h = ggx_half(alpha, hammersley(s, SAMPLES));
                let v_dot_h = v.dot(h);
                let l = 2.0 * v_dot_h * h - v;
                let n_dot_l = l.z;
                let n_dot_h = h.z;
                if n_dot_l <= 0.0 || v_dot_h <= 0.0 {
                    continue;
                }
                let lambda_v = n_dot_l * (n_dot_v * n_dot_v * (1.0 - a2) + a2).sqrt();
                let lambda_l = n_dot_v * (n_dot_l * n_dot_l * (1.0 - a2) + a2).sqrt();
                let vis = 0.5 / (lambda_v + lambda_l);
                // BRDF · cos / pdf with pdf = D · n·h / (4 v·h): the D cancels.
                let g = vis * 4.0 * n_dot_l * v_dot_h / n_dot_h;
                let fc = (1.0 - v_dot_h).powi(5);
                a += ((1.0 - fc) * g) as f64;
                b += (fc * g) as f64;
            }
            [
                (a / SAMPLES as f64).clamp(0.0, 1.0) as f32,
                (b / SAMPLES as f64).clamp(0.0, 1.0) as f32,
            ]
        })
        .collect())
}

/// The thesis' roughness approximation (Algorithm 3), for materials without roughness: a
/// view-dependent specular weight `cosθ · (1 − cosθ)⁵` with `cosθ = max(n·v, 0)`, and the
/// ambient term `(1 − specular) · irradiance` (the irradiance-map sample, linear RGB).
/// Non-unit vectors are normalised; zero or non-finite ones give `cosθ = 0`.
pub fn roughness_approximation(normal: Vec3, view: Vec3, irradiance: [f32; 3]) -> (f32, [f32; 3]) {
    let c = normal.normalize_or_zero().dot(view.normalize_or_zero());
    let cos_theta = if c.is_finite() { c.max(0.0) } else { 0.0 };
    let specular = cos_theta * (1.0 - cos_theta).powi(5);
    (specular, irradiance.map(|v| (1.0 - specular) * v))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn constant(size: u32, c: [f32; 3]) -> CubeLevel {
        CubeLevel {
            size,
            texels: vec![c; (6 * size * size) as usize],
        }
    }

    #[test]
    fn constant_environment_stays_constant_at_every_level() {
        let map = prefilter_ggx(&constant(16, [0.3, 1.0, 7.0]), 5, 32).unwrap();
        assert_eq!(map.levels.len(), 5);
        assert_eq!(map.levels[4].size, 1);
        for level in &map.levels {
            for t in &level.texels {
                assert!(
                    (t[0] - 0.3).abs() < 1e-5 && (t[2] - 7.0).abs() < 1e-4,
                    "{t:?}"
                );
            }
        }
    }

    #[test]
    fn rough_levels_blur_a_bright_spot_and_keep_energy_near_it() {
        // One bright texel on +Y: the mirror level keeps it sharp, rougher levels spread it, and
        // the texel facing it stays the brightest.
        let mut base = constant(16, [0.0; 3]);
        let centre = 2 * 256 + 8 * 16 + 8;
        base.texels[centre] = [100.0; 3];
        let map = prefilter_ggx(&base, 4, 256).unwrap();
        let up = sample_cube(&map.levels[2], Vec3::Y)[0];
        let side = sample_cube(&map.levels[2], Vec3::X)[0];
        assert!(up > 0.0 && up > 10.0 * side.max(1e-6), "{up} {side}");
        assert_eq!(
            sample_cube(&map.levels[0], Vec3::Y.lerp(Vec3::X, 0.05))[0],
            100.0
        );
    }

    #[test]
    fn dfg_is_bounded_and_sums_to_one_for_a_mirror_at_normal_incidence() {
        let lut = dfg_lut(32).unwrap();
        assert!(lut.iter().flatten().all(|v| (0.0..=1.0).contains(v)));
        let [a, b] = lut[31]; // smoothest row, n·v closest to 1
        assert!((a + b - 1.0).abs() < 0.03, "{a} {b}");
        assert!(
            b < 0.01,
            "Fresnel term at normal incidence should vanish, got {b}"
        );
        // A + B is the directional albedo ∫ D·V·(n·l) dω of the specular lobe with F = 1: check
        // against a brute-force integral over the hemisphere, independent of importance sampling.
        for (j, i) in [(31, 0), (31, 31), (16, 16), (8, 24)] {
            let [a, b] = lut[j * 32 + i];
            let roughness = (j as f32 + 0.5) / 32.0;
            let alpha = roughness * roughness;
            let a2 = alpha * alpha;
            let n_dot_v = (i as f32 + 0.5) / 32.0;
            let v = Vec3::new((1.0 - n_dot_v * n_dot_v).sqrt(), 0.0, n_dot_v);
            let steps = 400;
            let mut e = 0.0f64;
            for t in 0..steps {
                let cos_t = (t as f32 + 0.5) / steps as f32;
                let sin_t = (1.0 - cos_t * cos_t).sqrt();
                for p in 0..2 * steps {
                    let phi = (p as f32 + 0.5) / (2 * steps) as f32 * 2.0 * std::f32::consts::PI;
                    let l = Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t);
                    let h = (l + v).normalize();
                    let n_dot_l = l.z;
                    let vis = 0.5
                        / (n_dot_l * (n_dot_v * n_dot_v * (1.0 - a2) + a2).sqrt()
                            + n_dot_v * (n_dot_l * n_dot_l * (1.0 - a2) + a2).sqrt());
                    // dω = d(cosθ) dφ
                    let d_omega =
                        (1.0 / steps as f32) * (2.0 * std::f32::consts::PI / (2 * steps) as f32);
                    e += (ggx_d(alpha, h.z) * vis * n_dot_l * d_omega) as f64;
                }
            }
            assert!(
                ((a + b) as f64 - e).abs() < 0.03,
                "({j}, {i}): {a} + {b} vs {e}"
            );
        }
        assert!(dfg_lut(0).is_err());
    }

    #[test]
    fn roughness_approximation_follows_algorithm_3() {
        let (s, amb) = roughness_approximation(Vec3::Z, Vec3::Z, [1.0; 3]);
        assert_eq!(s, 0.0);
        assert_eq!(amb, [1.0; 3]);
        let (s, _) = roughness_approximation(Vec3::Z, Vec3::X, [1.0; 3]);
        assert_eq!(s, 0.0);
        let v = Vec3::new(1.0, 0.0, 0.5).normalize();
        let (s, amb) = roughness_approximation(Vec3::Z, v, [2.0; 3]);
        let c = v.z;
        assert!((s - c * (1.0 - c).powi(5)).abs() < 1e-6);
        assert!((amb[0] - 2.0 * (1.0 - s)).abs() < 1e-6);
        let (s, _) = roughness_approximation(Vec3::ZERO, Vec3::new(f32::NAN, 0.0, 0.0), [1.0; 3]);
        assert_eq!(s, 0.0);
    }

    #[test]
    fn bad_cubes_are_named() {
        let mut c = constant(4, [1.0; 3]);
        c.texels[3] = [f32::NAN; 3];
        assert!(prefilter_ggx(&c, 3, 8)
            .unwrap_err()
            .to_string()
            .contains("finite"));
        let short = CubeLevel {
            size: 4,
            texels: vec![[0.0; 3]; 10],
        };
        assert!(prefilter_ggx(&short, 3, 8).is_err());
        assert!(prefilter_ggx(&constant(4, [1.0; 3]), 0, 8).is_err());
        assert_eq!(sample_cube(&short, Vec3::X), [0.0; 3]);
    }
}
