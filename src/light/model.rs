//! The lighting model every stage agrees on: what a light is, how spherical-harmonics irradiance
//! is stored, and how a cube map's texels map to directions.
//!
//! The estimator (this module) produces these types, a host may give its own, and the renderer
//! consumes them. Positions and directions are in the left camera's frame (= world unless the host
//! gives a pose): +X right, +Y up, the camera looks along −Z, metres. Light values are linear and
//! relative to the photo's exposure (a pixel of 1.0 is the photo's white).

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// What kind of emitter a [`Light`] is.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LightKind {
    /// Infinitely far away (sun, a window seen from far): only `direction` and the angular size
    /// matter.
    Directional = 0,
    /// A sphere (a bare bulb) at `position` of radius `size / 2`; `size` 0 is a point light.
    Point = 1,
    /// A one-sided disc (a ceiling panel, a window) at `position` of diameter `size`, emitting
    /// into the half-space `direction` points into.
    Area = 2,
}

/// One light source.
///
/// `intensity` is linear RGB relative to the photo's exposure:
/// - `Directional`: the irradiance it gives a surface facing it (so a white Lambertian surface
///   facing it has radiance `intensity / π`);
/// - `Point` and `Area`: radiant intensity (per steradian), of a point in every direction, of a
///   disc along its axis (falling off with the cosine away from it). Irradiance at distance `r`
///   on a surface facing the light is `intensity / r²`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Light {
    /// Kind of emitter.
    pub kind: LightKind,
    /// Centre, metres (ignored for `Directional`).
    pub position: [f32; 3],
    /// Unit direction the light travels (from the light towards the scene): the direction of a
    /// `Directional` light, the axis of an `Area` light; ignored for `Point`.
    pub direction: [f32; 3],
    /// Size of the emitter: diameter in metres (`Point`, `Area`), full angular diameter in
    /// degrees (`Directional`, in [0, 90)). 0 means a delta light (hard shadows).
    pub size: f32,
    /// Linear RGB intensity, see the type's documentation; every channel ≥ 0.
    pub intensity: [f32; 3],
    /// How sure the estimator is, in [0, 1] (1 for lights given by a host).
    pub confidence: f32,
}

impl Light {
    /// A directional light travelling along `direction` (normalised here).
    pub fn directional(
        direction: [f32; 3],
        angular_diameter_deg: f32,
        irradiance: [f32; 3],
    ) -> Light {
        Light {
            kind: LightKind::Directional,
            position: [0.0; 3],
            direction: Vec3::from(direction).normalize_or_zero().to_array(),
            size: angular_diameter_deg,
            intensity: irradiance,
            confidence: 1.0,
        }
    }

    /// A point light (a sphere of diameter `diameter` metres, 0 for a point) at `position`
    /// (metres) of radiant intensity `intensity`.
    pub fn point(position: [f32; 3], diameter: f32, intensity: [f32; 3]) -> Light {
        Light {
            kind: LightKind::Point,
            position,
            direction: [0.0, -1.0, 0.0],
            size: diameter,
            intensity,
            confidence: 1.0,
        }
    }

    /// Checks that every value is finite and in range.
    ///
    /// # Errors
    /// `InvalidArgument` naming the field: a non-finite value, a zero-length direction where the
    /// kind needs one, a negative size, an angular size outside [0, 90) degrees, a negative
    /// intensity channel, or a confidence outside [0, 1].
    pub fn validate(&self) -> Result<()> {
        let finite = |what: &str, v: &[f32]| {
            if v.iter().all(|c| c.is_finite()) {
                Ok(())
            } else {
                Err(Error::invalid(format!(
                    "light {what} must be finite, got {v:?}"
                )))
            }
        };
        finite("position", &self.position)?;
        finite("direction", &self.direction)?;
        finite("size", &[self.size])?;
        finite("intensity", &self.intensity)?;
        if self.kind != LightKind::Point && Vec3::from(self.direction).length() < 1e-6 {
            return Err(Error::invalid(format!(
                "light direction must not be zero for a {:?} light",
                self.kind
            )));
        }
        if self.size < 0.0 {
            return Err(Error::invalid(format!(
                "light size must be >= 0, got {}",
                self.size
            )));
        }
        if self.kind == LightKind::Directional && self.size >= 90.0 {
            return Err(Error::invalid(format!(
                "directional light angular diameter must be in [0, 90) degrees, got {}",
                self.size
            )));
        }
        if self.intensity.iter().any(|c| *c < 0.0) {
            return Err(Error::invalid(format!(
                "light intensity must be >= 0 in every channel, got {:?}",
                self.intensity
            )));
        }
        if !(0.0..=1.0).contains(&self.confidence) {
            return Err(Error::invalid(format!(
                "light confidence must be in [0, 1], got {}",
                self.confidence
            )));
        }
        Ok(())
    }

    /// How far from a positional light's centre its own body reaches, metres: 1.5 radii (0 for a
    /// directional light). A lamp seen in the photo sits behind or on its own pixels, so surfaces
    /// within this distance are the lamp itself and must not shadow its light.
    pub fn body_reach(&self) -> f32 {
        match self.kind {
            LightKind::Directional => 0.0,
            LightKind::Point | LightKind::Area => 0.75 * self.size,
        }
    }

    /// The unoccluded geometric term of this light at a surface point `p` with unit normal `n`:
    /// `max(0, n·l)` for a directional light; that over the squared distance (at least 1 cm²)
    /// for a light at a position, times the disc's facing cosine for an area light. Multiplied
    /// by `intensity / π` it is the irradiance over π, so a surface of albedo ρ shows
    /// `ρ · intensity / π · term` (0 when the surface faces away or lies behind a disc).
    pub fn unshadowed_term(&self, p: Vec3, n: Vec3) -> f32 {
        let (l, dist) = self.towards(p);
        let cos = n.dot(l);
        if cos.is_nan() || cos <= 0.0 {
            return 0.0;
        }
        match self.kind {
            LightKind::Directional => cos,
            LightKind::Point | LightKind::Area => {
                let facing = if self.kind == LightKind::Area {
                    (-l).dot(Vec3::from(self.direction).normalize_or_zero())
                        .max(0.0)
                } else {
                    1.0
                };
                cos * facing / (dist * dist).max(1e-4)
            }
        }
    }

    /// The unit direction from a surface point `p` towards the light, and the distance to it
    /// (infinite for a directional light).
    pub fn towards(&self, p: Vec3) -> (Vec3, f32) {
        match self.kind {
            LightKind::Directional => (
                -Vec3::from(self.direction).normalize_or_zero(),
                f32::INFINITY,
            ),
            LightKind::Point | LightKind::Area => {
                let d = Vec3::from(self.position) - p;
                let r = d.length();
                (if r > 0.0 { d / r } else { Vec3::Y }, r)
            }
        }
    }
}

/// The polynomial of each of the nine coefficients of [`Sh9`] at unit normal `n`, in ARCore's and
/// Filament's order: 1, y, z, x, xy, yz, 3z² − 1, xz, x² − y².
pub fn sh9_basis_polynomials(n: Vec3) -> [f32; 9] {
    [
        1.0,
        n.y,
        n.z,
        n.x,
        n.x * n.y,
        n.y * n.z,
        3.0 * n.z * n.z - 1.0,
        n.x * n.z,
        n.x * n.x - n.y * n.y,
    ]
}

/// Ambient light as nine RGB spherical-harmonics coefficients (27 floats).
///
/// Convention (Filament's "pre-scaled" irradiance, also ARCore's coefficient order): the real SH
/// projection `L_lm` of the incoming radiance is convolved with the clamped cosine (Ramamoorthi &
/// Hanrahan 2001: Â₀ = π, Â₁ = 2π/3, Â₂ = π/4), divided by π, and each band's normalisation
/// constant is folded in, so that the *diffuse radiance* of a white Lambertian surface with unit
/// normal `n` is simply `Σ_i coefficients[i] · P_i(n)` with `P` from [`sh9_basis_polynomials`]
/// (irradiance is π times that). The shader evaluates exactly this polynomial.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Sh9 {
    /// Coefficient-major: `coefficients[i] = [r, g, b]` of polynomial `i`.
    pub coefficients: [[f32; 3]; 9],
}

/// Per coefficient, the factor that turns the radiance projection `L_lm` (orthonormal real SH,
/// same order) into the pre-scaled coefficient of [`Sh9`]: `K_lm · Â_l / π` times the factor that
/// turns `Y_lm` into the polynomial.
pub const SH9_RADIANCE_TO_PRESCALED: [f32; 9] = {
    // Y00 = 0.282095; Y1m = 0.488603 · (y, z, x); Y2-2 = 1.092548 xy; Y2-1 = 1.092548 yz;
    // Y20 = 0.315392 (3z² − 1); Y21 = 1.092548 xz; Y22 = 0.546274 (x² − y²).
    // Band factors Â_l / π: 1, 2/3, 1/4.
    [
        0.282_095,
        0.488_603 * 2.0 / 3.0,
        0.488_603 * 2.0 / 3.0,
        0.488_603 * 2.0 / 3.0,
        1.092_548 / 4.0,
        1.092_548 / 4.0,
        0.315_392 / 4.0,
        1.092_548 / 4.0,
        0.546_274 / 4.0,
    ]
};

impl Sh9 {
    /// Pre-scales the orthonormal real-SH projection of a radiance field (`radiance[i]` for
    /// `Y_00, Y_1−1, Y_10, Y_11, Y_2−2, Y_2−1, Y_20, Y_21, Y_22`) into this convention.
    pub fn from_radiance_projection(radiance: [[f32; 3]; 9]) -> Sh9 {
        let mut coefficients = [[0.0; 3]; 9];
        for (i, c) in coefficients.iter_mut().enumerate() {
            *c = radiance[i].map(|v| v * SH9_RADIANCE_TO_PRESCALED[i]);
        }
        Sh9 { coefficients }
    }

    /// Diffuse radiance of a white Lambertian surface with unit normal `n` (irradiance / π),
    /// clamped at 0 because a 9-term fit can ring below zero.
    pub fn diffuse_radiance(&self, n: Vec3) -> [f32; 3] {
        let p = sh9_basis_polynomials(n);
        let mut out = [0.0f32; 3];
        for (c, w) in self.coefficients.iter().zip(p) {
            for k in 0..3 {
                out[k] += c[k] * w;
            }
        }
        out.map(|v| v.max(0.0))
    }

    /// The 27 floats in ARCore's layout: coefficient-major, RGB per coefficient.
    pub fn to_array(&self) -> [f32; 27] {
        let mut out = [0.0; 27];
        for (i, c) in self.coefficients.iter().enumerate() {
            out[3 * i..3 * i + 3].copy_from_slice(c);
        }
        out
    }

    /// The inverse of [`Sh9::to_array`].
    ///
    /// # Errors
    /// `InvalidArgument` when a value is not finite.
    pub fn from_array(values: &[f32; 27]) -> Result<Sh9> {
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return Err(Error::invalid(format!(
                "spherical-harmonics coefficient {i} must be finite, got {}",
                values[i]
            )));
        }
        let mut coefficients = [[0.0; 3]; 9];
        for (i, c) in coefficients.iter_mut().enumerate() {
            c.copy_from_slice(&values[3 * i..3 * i + 3]);
        }
        Ok(Sh9 { coefficients })
    }
}

/// Cube-map faces in the order GPUs store them as array layers: +X, −X, +Y, −Y, +Z, −Z.
pub const CUBE_FACES: usize = 6;

/// The unit direction through texel coordinates `(s, t)` ∈ [0, 1]² of cube face `face` (0..6 in
/// [`CUBE_FACES`] order; `t = 0` is the face's first row), following the Vulkan/D3D/WebGPU
/// face-selection table so that a shader sampling the cube with this direction reads that texel.
/// For texel `(i, j)` of an `n × n` face use `s = (i + 0.5) / n`, `t = (j + 0.5) / n`.
pub fn cube_direction(face: usize, s: f32, t: f32) -> Vec3 {
    let sc = 2.0 * s - 1.0;
    let tc = 2.0 * t - 1.0;
    let d = match face {
        0 => Vec3::new(1.0, -tc, -sc),
        1 => Vec3::new(-1.0, -tc, sc),
        2 => Vec3::new(sc, 1.0, tc),
        3 => Vec3::new(sc, -1.0, -tc),
        4 => Vec3::new(sc, -tc, 1.0),
        _ => Vec3::new(-sc, -tc, -1.0),
    };
    d.normalize()
}

/// The face and texel coordinates `(s, t)` ∈ [0, 1]² a direction samples; the inverse of
/// [`cube_direction`]. A zero direction reads face +X's centre.
pub fn cube_texel(direction: Vec3) -> (usize, f32, f32) {
    let a = direction.abs();
    let (face, sc, tc, ma) = if a.x >= a.y && a.x >= a.z {
        if direction.x >= 0.0 {
            (0, -direction.z, -direction.y, a.x)
        } else {
            (1, direction.z, -direction.y, a.x)
        }
    } else if a.y >= a.z {
        if direction.y >= 0.0 {
            (2, direction.x, direction.z, a.y)
        } else {
            (3, direction.x, -direction.z, a.y)
        }
    } else if direction.z >= 0.0 {
        (4, direction.x, -direction.y, a.z)
    } else {
        (5, -direction.x, -direction.y, a.z)
    };
    if ma <= 0.0 {
        return (0, 0.5, 0.5);
    }
    (face, 0.5 * (sc / ma + 1.0), 0.5 * (tc / ma + 1.0))
}

/// An HDR cube map of linear RGB radiance with its mip chain.
///
/// `levels[0]` is the full-resolution map; for a prefiltered map, level `k` of `n` holds the GGX
/// prefiltered radiance for perceptual roughness `k / (n − 1)` (Filament's split-sum layout).
/// Each level holds [`CUBE_FACES`] faces of `size × size` texels, row-major, face after face.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CubeMap {
    /// One entry per mip level, largest first.
    pub levels: Vec<CubeLevel>,
}

/// One mip level of a [`CubeMap`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CubeLevel {
    /// Edge length of each face, texels.
    pub size: u32,
    /// `6 · size · size` texels: face-major ([`CUBE_FACES`] order), then row-major.
    pub texels: Vec<[f32; 3]>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cube_direction_and_texel_are_inverse() {
        for face in 0..CUBE_FACES {
            for (s, t) in [(0.5, 0.5), (0.1, 0.8), (0.9, 0.2), (0.3, 0.3)] {
                let d = cube_direction(face, s, t);
                let (f, s2, t2) = cube_texel(d * 3.0);
                assert_eq!(f, face);
                assert!(
                    (s - s2).abs() < 1e-5 && (t - t2).abs() < 1e-5,
                    "{face} {s} {t}"
                );
            }
        }
        // Face centres are the axes.
        assert!(cube_direction(0, 0.5, 0.5).abs_diff_eq(Vec3::X, 1e-6));
        assert!(cube_direction(5, 0.5, 0.5).abs_diff_eq(-Vec3::Z, 1e-6));
        // On +Z the first row is up (+Y) and the first column is −X.
        assert!(cube_direction(4, 0.0, 0.0).y > 0.0);
        assert!(cube_direction(4, 0.0, 0.5).x < 0.0);
    }

    #[test]
    fn sh9_of_constant_radiance_is_that_radiance() {
        // Constant radiance L projects to L_00 = L · 2√π; the diffuse radiance of any surface
        // under it is L.
        let l = [0.5f32, 1.0, 2.0];
        let mut proj = [[0.0f32; 3]; 9];
        proj[0] = l.map(|v| v * 2.0 * std::f32::consts::PI.sqrt());
        let sh = Sh9::from_radiance_projection(proj);
        for n in [
            Vec3::X,
            Vec3::Y,
            -Vec3::Z,
            Vec3::new(1.0, 1.0, 1.0).normalize(),
        ] {
            let d = sh.diffuse_radiance(n);
            for k in 0..3 {
                assert!((d[k] - l[k]).abs() < 1e-3 * l[k], "{d:?}");
            }
        }
        let round = Sh9::from_array(&sh.to_array()).unwrap();
        assert_eq!(round, sh);
        let mut bad = sh.to_array();
        bad[4] = f32::NAN;
        assert!(Sh9::from_array(&bad).is_err());
    }

    #[test]
    fn light_validation_names_the_field() {
        let ok = Light::directional([0.0, -1.0, 0.0], 0.5, [1.0; 3]);
        ok.validate().unwrap();
        let e = Light {
            intensity: [-1.0, 0.0, 0.0],
            ..ok
        }
        .validate()
        .unwrap_err();
        assert!(e.to_string().contains("intensity"));
        let e = Light {
            direction: [0.0; 3],
            ..ok
        }
        .validate()
        .unwrap_err();
        assert!(e.to_string().contains("direction"));
        let e = Light { size: 95.0, ..ok }.validate().unwrap_err();
        assert!(e.to_string().contains("angular"));
        let e = Light {
            position: [f32::NAN, 0.0, 0.0],
            ..ok
        }
        .validate()
        .unwrap_err();
        assert!(e.to_string().contains("position"));
        let point = Light {
            kind: LightKind::Point,
            direction: [0.0; 3],
            position: [0.0, 2.0, -1.0],
            ..ok
        };
        point.validate().unwrap();
        let (dir, r) = point.towards(Vec3::new(0.0, 0.0, -1.0));
        assert!(dir.abs_diff_eq(Vec3::Y, 1e-6) && (r - 2.0).abs() < 1e-6);
    }
}
