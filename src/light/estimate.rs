//! The whole illumination estimate in one call: shadow mask, in-view sources, fitted lights and
//! the environment around the insertion point, from a photo with depth (and normals when known).

use glam::Vec3;

use super::environment::{Environment, EnvironmentOptions, PhotoReprojection};
use super::filters::{check_same, check_size, luminance};
use super::fit::{fit_lights, FitInputs, FitOptions, LightFit};
use super::model::{Light, LightKind};
use super::normals::normals_from_depth;
use super::relight::proxy_shading;
use super::shadow_mask::{continuity_regions, shadow_mask, ShadowOptions, NO_REGION};
use super::sources::{detect_sources, SourceOptions};
use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::image::Raster;
use crate::trace::time_part;

/// Options of [`estimate_lighting`]: one set per stage.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EstimateOptions {
    /// Shadow mask.
    pub shadow: ShadowOptions,
    /// In-view sources (its `up` is replaced by the estimate's up).
    pub sources: SourceOptions,
    /// Out-of-view light fit (its `insertion_point` is replaced by the estimate's).
    pub fit: FitOptions,
    /// Environment.
    pub environment: EnvironmentOptions,
}

/// Everything [`estimate_lighting`] found.
#[derive(Debug, Clone)]
pub struct LightingEstimate {
    /// Soft shadow mask of the photo, [0, 1].
    pub shadow_mask: Raster<f32>,
    /// Continuous regions used by the mask and the fit.
    pub regions: Raster<u32>,
    /// Normals used (given, or from depth).
    pub normals: Raster<[f32; 3]>,
    /// Sources seen in the photo, as detected (before the fit re-scales them).
    pub sources: Vec<Light>,
    /// The fit: main light, ambient, every light, fallback flag.
    pub fit: LightFit,
    /// The environment around `insertion_point`, with the fitted lights drawn in.
    pub environment: Environment,
    /// Where the environment was built, camera frame, metres.
    pub insertion_point: [f32; 3],
    /// Wall-clock milliseconds of each part, in order: `lighting.normals` (only when computed
    /// from depth), `lighting.regions`, `lighting.mask`, `lighting.sources`, `lighting.fit`,
    /// `lighting.reprojection`, `lighting.relight` (not after a fallback), `lighting.calibration`,
    /// `lighting.environment`.
    pub timings: Vec<(String, f64)>,
}

/// Where to put the environment when the caller names no point: the median point of the pixels
/// whose surface faces up (a floor or table top), 2 cm above it; the median of all points when none
/// faces up; 2 m in front of the camera without depth.
fn default_insertion_point(
    depth: &Raster<f32>,
    normals: &Raster<[f32; 3]>,
    camera: &Camera,
    up: Vec3,
) -> Vec3 {
    let (w, h) = (depth.width(), depth.height());
    let step = ((w * h) as f64 / 20_000.0).sqrt().ceil().max(1.0) as usize;
    let (mut support, mut all) = (Vec::new(), Vec::new());
    for y in (0..h).step_by(step) {
        for x in (0..w).step_by(step) {
            if let Some(p) = camera.unproject(x as f32 + 0.5, y as f32 + 0.5, *depth.get(x, y)) {
                all.push(p);
                if Vec3::from(*normals.get(x, y)).dot(up) > 0.9 {
                    support.push(p);
                }
            }
        }
    }
    let pick = if support.len() >= 20 {
        &mut support
    } else {
        &mut all
    };
    if pick.is_empty() {
        return Vec3::new(0.0, 0.0, -2.0);
    }
    let med = |f: fn(&Vec3) -> f32| {
        let mut v: Vec<f32> = pick.iter().map(f).collect();
        let mid = v.len() / 2;
        *v.select_nth_unstable_by(mid, f32::total_cmp).1
    };
    Vec3::new(med(|p| p.x), med(|p| p.y), med(|p| p.z)) + up * 0.02
}

/// The median albedo of a photo's surfaces is taken to lie in this range: no surface reflects
/// more light than it receives, and about 0.05 is as dark as common materials get (charcoal,
/// black cloth); see [`calibrate_to_environment`].
const MEDIAN_ALBEDO_RANGE: (f32, f32) = (0.05, 1.0);

/// Puts the fitted lights on the photo's scale. The fit finds each light's strength against the
/// ambient term from the shading contrast, which does not depend on the albedo, but the overall
/// scale only from an assumed median albedo, and the colour by grey world, which paints the
/// light the colour of a wooden room. The photo itself measures the ambient: the surfaces around
/// the insertion point, re-projected (without lights and without LDR expansion), are the light
/// that reaches a support surface besides the lights. So the ambient becomes the diffuse
/// radiance of that environment facing `up`, every fitted intensity is scaled by the same factor
/// (in luminance), and lights out of view, whose colour nothing measures, are made neutral (the
/// photo is taken as white-balanced). Sources the fallback kept with their detected intensities
/// stay as they are.
///
/// The factor is `assumed_albedo` over the photo's true median albedo (the fit's albedos and
/// lights trade off by it), so it is kept to what a median albedo between
/// [`MEDIAN_ALBEDO_RANGE`]'s ends allows. Unbounded, a fit that gives the ambient term next to
/// nothing (a wide light overhead taking the ambient's part of the shading) made its lights as
/// many times too bright as its ambient was too small, and a fit with no ambient at all was left
/// uncalibrated.
fn calibrate_to_environment(
    mut fit: LightFit,
    photo: &Raster<[f32; 3]>,
    reprojection: &PhotoReprojection,
    up: Vec3,
    shading: Option<&Raster<f32>>,
    assumed_albedo: f32,
    options: &EnvironmentOptions,
) -> Result<LightFit> {
    // `luminance` is finite and ≥ 0 whatever the channels hold.
    let fit_ambient = luminance(fit.ambient);
    let ambient_env = Environment::from_reprojection(
        photo,
        reprojection,
        up,
        &[],
        shading,
        &EnvironmentOptions {
            ldr_peak: 1.0,
            ..*options
        },
    )?;
    let measured = ambient_env.sh9.diffuse_radiance(up);
    let measured_lum = luminance(measured);
    if measured_lum <= 0.0 {
        return Ok(fit);
    }
    let (min_albedo, max_albedo) = MEDIAN_ALBEDO_RANGE;
    // No ambient in the fit: the ratio is infinite, and the bound is where it stops.
    let lum_scale = (measured_lum / fit_ambient)
        .clamp(assumed_albedo / max_albedo, assumed_albedo / min_albedo);
    let scaled = |l: &Light| Light {
        intensity: if l.kind == LightKind::Directional {
            // Out of view: no colour of its own is measured; white balance makes it neutral (a
            // fitted point light out of view comes neutral from the fit).
            [luminance(l.intensity) * lum_scale; 3]
        } else {
            l.intensity.map(|v| v * lum_scale)
        },
        ..*l
    };
    let main = fit.main;
    for l in fit.lights.iter_mut() {
        if !fit.fallback_used || *l == main {
            *l = scaled(l);
        }
    }
    fit.main = scaled(&main);
    fit.ambient = measured;
    Ok(fit)
}

/// Runs every illumination stage on a linear RGB photo with depth (metres along the optical axis,
/// NaN/inf unknown). `normals` (camera frame, zero = unknown) are computed from depth when not
/// given; `up` is gravity up in the camera frame (the support surfaces' normal, or +Y);
/// `insertion_point` is where the environment is centred (see `default_insertion_point` in the
/// source for the default).
///
/// # Errors
/// As the stages: `SizeMismatch` for rasters or a camera of another size, `InvalidArgument` for an
/// empty photo, bad options, a zero `up` or a non-finite point.
pub fn estimate_lighting(
    photo: &Raster<[f32; 3]>,
    depth: &Raster<f32>,
    normals: Option<&Raster<[f32; 3]>>,
    camera: &Camera,
    up: [f32; 3],
    insertion_point: Option<[f32; 3]>,
    options: &EstimateOptions,
) -> Result<LightingEstimate> {
    check_size("photo", photo)?;
    check_same("depth map", photo, depth)?;
    let up_v = Vec3::from(up);
    if !up_v.is_finite() || up_v.length() < 1e-6 {
        return Err(Error::invalid(format!(
            "up must be a finite non-zero vector, got {up:?}"
        )));
    }
    let up_v = up_v.normalize();
    let mut timings = Vec::new();
    let normals = match normals {
        Some(n) => {
            check_same("normal map", photo, n)?;
            n.clone()
        }
        None => time_part(&mut timings, "lighting.normals", || {
            normals_from_depth(depth, camera, 0.05)
        })?,
    };
    let min_region = (photo.len() / 2000).max(20);
    let regions = time_part(&mut timings, "lighting.regions", || {
        continuity_regions(depth, Some(&normals), 0.04, 25.0, min_region)
    })?;
    let mask = time_part(&mut timings, "lighting.mask", || {
        shadow_mask(photo, Some(&regions), &options.shadow)
    })?;
    let sources = time_part(&mut timings, "lighting.sources", || {
        detect_sources(
            photo,
            Some(depth),
            camera,
            &SourceOptions {
                up,
                ..options.sources
            },
        )
    })?;
    let point = match insertion_point {
        Some(p) => {
            let p = Vec3::from(p);
            if !p.is_finite() {
                return Err(Error::invalid(format!(
                    "insertion point must be finite, got {p}"
                )));
            }
            p
        }
        None => default_insertion_point(depth, &normals, camera, up_v),
    };
    // Light pixels themselves are not shading samples.
    let fit_regions = Raster::from_fn(regions.width(), regions.height(), |x, y| {
        let c = photo.get(x, y);
        if c.iter().all(|v| v.is_finite() && *v >= 0.98) {
            NO_REGION
        } else {
            *regions.get(x, y)
        }
    });
    let fit = time_part(&mut timings, "lighting.fit", || {
        fit_lights(
            &FitInputs {
                photo,
                depth,
                normals: &normals,
                regions: &fit_regions,
                shadow_mask: Some(&mask),
                camera,
                up,
            },
            &sources,
            &FitOptions {
                insertion_point: Some(point.to_array()),
                ..options.fit
            },
        )
    })?;
    // One ray march from the insertion point serves both the ambient calibration and the
    // environment handed out.
    let reprojection = time_part(&mut timings, "lighting.reprojection", || {
        PhotoReprojection::new(
            photo,
            Some(depth),
            camera,
            point,
            options.environment.face_size,
        )
    })?;
    // Unseen directions are filled with surfaces lit as the fit says; a fallback inferred
    // nothing, so they are filled by elevation alone.
    let shading = if fit.fallback_used {
        None
    } else {
        Some(time_part(&mut timings, "lighting.relight", || {
            proxy_shading(
                &reprojection,
                depth,
                &normals,
                camera,
                luminance(fit.ambient),
                &fit.lights,
            )
        })?)
    };
    let fit = time_part(&mut timings, "lighting.calibration", || {
        calibrate_to_environment(
            fit,
            photo,
            &reprojection,
            up_v,
            shading.as_ref(),
            options.fit.albedo,
            &options.environment,
        )
    })?;
    let environment = time_part(&mut timings, "lighting.environment", || {
        Environment::from_reprojection(
            photo,
            &reprojection,
            up_v,
            &fit.lights,
            shading.as_ref(),
            &options.environment,
        )
    })?;
    Ok(LightingEstimate {
        shadow_mask: mask,
        regions,
        normals,
        sources,
        fit,
        environment,
        insertion_point: point.to_array(),
        timings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fit(lights: Vec<Light>, ambient: [f32; 3], fallback_used: bool) -> LightFit {
        LightFit {
            main: lights[lights.len() - 1],
            ambient,
            lights,
            fallback_used,
            residual: 0.2,
            shadow_disagreement: 0.0,
            samples: 1000,
        }
    }

    #[test]
    fn the_fit_is_put_on_the_scale_of_the_measured_ambient() {
        // Nothing but sky of radiance (0.4, 0.3, 0.2) in view: the ambient a surface facing up
        // gets is that radiance, whatever albedo the fit assumed.
        let camera = Camera::from_focal(40.0, 64, 48).unwrap();
        let photo = Raster::filled(64, 48, [0.4f32, 0.3, 0.2]);
        let depth = Raster::filled(64, 48, f32::NAN);
        let sun = Light::directional([0.3, -1.0, 0.0], 4.0, [2.0, 1.0, 0.5]);
        let lamp = Light {
            kind: LightKind::Area,
            position: [0.5, 1.0, -2.0],
            direction: [0.0, -1.0, 0.0],
            size: 0.2,
            intensity: [0.3, 0.2, 0.1],
            confidence: 0.8,
        };
        let ambient = [0.1f32, 0.05, 0.02];
        // The calibration around a point 2 m ahead of the camera, up along +Y.
        let calibrate = |fit: LightFit, photo: &Raster<[f32; 3]>| {
            let options = EnvironmentOptions::default();
            let point = Vec3::new(0.0, 0.0, -2.0);
            let reprojection =
                PhotoReprojection::new(photo, Some(&depth), &camera, point, options.face_size)
                    .unwrap();
            calibrate_to_environment(fit, photo, &reprojection, Vec3::Y, None, 0.5, &options)
                .unwrap()
        };
        let out = calibrate(fit(vec![lamp, sun], ambient, false), &photo);
        for (a, b) in out.ambient.iter().zip([0.4, 0.3, 0.2]) {
            assert!((a - b).abs() < 0.02, "{:?}", out.ambient);
        }
        let scale = luminance(out.ambient) / luminance(ambient);
        // The out-of-view light keeps its strength against the ambient and becomes neutral.
        let s = out.lights[1].intensity;
        assert!(s[0] == s[1] && s[1] == s[2], "{s:?}");
        assert!((s[0] - luminance(sun.intensity) * scale).abs() < 1e-3 * s[0]);
        assert_eq!(out.main, out.lights[1]);
        // The in-view light keeps its colour.
        for k in 0..3 {
            let want = lamp.intensity[k] * scale;
            assert!((out.lights[0].intensity[k] - want).abs() < 1e-4 * want.max(1.0));
        }
        // A fallback keeps the sources it did not fit as they were.
        let out = calibrate(fit(vec![lamp, sun], ambient, true), &photo);
        assert_eq!(out.lights[0], lamp);
        assert!(out.lights[1].intensity[0] > sun.intensity[0]);
        // A black photo measures nothing and changes nothing.
        let black = Raster::filled(64, 48, [0.0f32; 3]);
        let before = fit(vec![lamp, sun], ambient, false);
        let out = calibrate(before.clone(), &black);
        assert_eq!(out, before);
        // A fit that gives the ambient term next to nothing, or nothing, would need a factor of
        // thousands, or an infinite one: it stops where the photo's median albedo would be 0.05
        // (the fit assumed 0.5), the same for both.
        for tiny in [1e-7f32, 0.0] {
            let out = calibrate(fit(vec![lamp, sun], [tiny; 3], false), &photo);
            let s = out.lights[1].intensity[0];
            assert!(
                (s - luminance(sun.intensity) * 10.0).abs() < 1e-3 * s,
                "ambient {tiny}: sun {s}"
            );
            assert!((luminance(out.ambient) - luminance([0.4, 0.3, 0.2])).abs() < 0.02);
        }
        // Nor can the factor make the photo's median albedo exceed 1 (a fit whose ambient alone
        // is brighter than the photo's).
        let out = calibrate(fit(vec![lamp, sun], [10.0; 3], false), &photo);
        let s = out.lights[1].intensity[0];
        assert!((s - luminance(sun.intensity) * 0.5).abs() < 1e-3 * s, "{s}");
    }
}
