//! The whole illumination estimate in one call: shadow mask, in-view sources, fitted lights and
//! the environment around the insertion point, from a photo with depth (and normals when known).

use glam::Vec3;

use super::environment::{Environment, EnvironmentOptions};
use super::filters::{check_same, check_size};
use super::fit::{fit_lights, FitInputs, FitOptions, LightFit};
use super::model::Light;
use super::normals::normals_from_depth;
use super::shadow_mask::{continuity_regions, shadow_mask, ShadowOptions, NO_REGION};
use super::sources::{detect_sources, SourceOptions};
use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::image::Raster;

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
    let normals = match normals {
        Some(n) => {
            check_same("normal map", photo, n)?;
            n.clone()
        }
        None => normals_from_depth(depth, camera, 0.05)?,
    };
    let min_region = (photo.len() / 2000).max(20);
    let regions = continuity_regions(depth, Some(&normals), 0.04, 25.0, min_region)?;
    let mask = shadow_mask(photo, Some(&regions), &options.shadow)?;
    let sources = detect_sources(
        photo,
        Some(depth),
        camera,
        &SourceOptions {
            up,
            ..options.sources
        },
    )?;
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
    let fit = fit_lights(
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
    )?;
    let environment = Environment::from_photo_with_up(
        photo,
        Some(depth),
        camera,
        point,
        up_v,
        &fit.lights,
        &options.environment,
    )?;
    Ok(LightingEstimate {
        shadow_mask: mask,
        regions,
        normals,
        sources,
        fit,
        environment,
        insertion_point: point.to_array(),
    })
}
