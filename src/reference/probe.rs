//! The true radiance arriving at a point of a reference scene from every direction, by path
//! tracing: the yardstick for estimated environments and SH irradiance.

use glam::{Vec3, Vec3A};
use rayon::prelude::*;

use super::integrator::{Camera, RayCounts};
use super::sampling::Rng;
use super::{build_tracer, resolved_rig, validate_options, RenderOptions, SampleBudget, Scene};
use crate::error::{Error, Result};
use crate::light::{cube_direction, CubeLevel, CUBE_FACES};

/// Path-traced radiance arriving at `point` (in the left camera's frame of the rig as resolved by
/// `options`, metres) as a cube level of `face_size` texels in the camera frame, each the mean of
/// `options`' samples per pixel (a time budget counts as 16) of full paths (all bounces up to
/// `options.max_bounces`; lights and the environment seen directly included).
///
/// # Errors
/// `InvalidArgument` for an invalid scene or options, a non-finite point or a face size outside
/// 1..=512.
pub fn radiance_probe(
    scene: &Scene,
    options: &RenderOptions,
    point: [f32; 3],
    face_size: u32,
) -> Result<CubeLevel> {
    validate_options(options)?;
    if !point.iter().all(|v| v.is_finite()) {
        return Err(Error::invalid(format!(
            "probe point must be finite, got {point:?}"
        )));
    }
    if !(1..=512).contains(&face_size) {
        return Err(Error::invalid(format!(
            "probe face size must be in 1..=512, got {face_size}"
        )));
    }
    let spp = match options.samples {
        SampleBudget::PerPixel(n) => n,
        SampleBudget::Time(_) => 16,
    };
    let (rig, resolved) = resolved_rig(scene, options)?;
    let mut tracer = build_tracer(&resolved, rig, &[], options.max_bounces)?;
    let world = |v: Vec3| rig.right * v.x + rig.up * v.y - rig.forward * v.z;
    let origin = rig.eyes[0] + world(Vec3::from(point));
    let n = face_size as usize;
    let mut texels = Vec::with_capacity(CUBE_FACES * n * n);
    for face in 0..CUBE_FACES {
        // The face's unnormalised direction is forward + right·sc + up·(−tc), which is what the
        // tracer's camera produces for pixel (s·n, t·n) with focal n/2 and the centre at n/2.
        let raw = |s: f32, t: f32| {
            let d = cube_direction(face, s, t);
            d / d.abs().max_element()
        };
        let centre = raw(0.5, 0.5);
        tracer.camera = Camera {
            eyes: [origin, origin],
            right: world(raw(1.0, 0.5) - centre),
            up: world(raw(0.5, 0.0) - centre),
            forward: world(centre),
            focal: n as f64 / 2.0,
            cx: n as f64 / 2.0,
            cy: n as f64 / 2.0,
            width: n,
            height: n,
            baseline: rig.baseline,
        };
        let tracer = &tracer;
        let face_texels: Vec<[f32; 3]> = (0..n * n)
            .into_par_iter()
            .map(|k| {
                let (i, j) = (k % n, k / n);
                let mut sum = Vec3A::ZERO;
                let mut counts = RayCounts::default();
                for s in 0..spp {
                    let pixel = (face * n * n + k) as u64;
                    let mut rng = Rng::for_sample(options.seed, 7, pixel, s as u64);
                    let jitter = rng.uniform2();
                    let (radiance, _) = tracer.trace(
                        0,
                        i as f64 + jitter.x as f64,
                        j as f64 + jitter.y as f64,
                        &mut rng,
                        None,
                        &mut counts,
                    );
                    sum += radiance;
                }
                (sum / spp as f32).to_array()
            })
            .collect();
        texels.extend(face_texels);
    }
    Ok(CubeLevel {
        size: face_size,
        texels,
    })
}
