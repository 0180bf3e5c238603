//! How the fitted lights shade the surfaces around the insertion point, per direction of the
//! environment's grid: what lets the environment fill the directions the camera never saw with
//! surfaces lit as the fit says they are, rather than as copies of what was seen at the same
//! elevation (see `fill_by_elevation` in [`super::environment`]).
//!
//! Each cell of the equirect grid looks at a surface. Where the photo shows it, that surface is
//! the depth map's point and normal at the pixel the direction meets; where it does not, a
//! surface stands in, facing the insertion point, as far away as the median surface seen above
//! the point's horizon (the room's walls and ceiling). Its shading is the fit's model without cast shadows, `A + Σ_j I_j/π · g_j`
//! (the fit's ambient and lights, [`Light::unshadowed_term`]): the relative irradiance a
//! Lambertian surface there receives. Only ratios of it are used, so the scale of the fit
//! (before or after its calibration to the photo) does not matter.

use glam::Vec3;
use rayon::prelude::*;

use super::environment::{equirect_direction, PhotoReprojection};
use super::filters::{check_same, luminance};
use super::model::Light;
use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::image::Raster;

/// The relative irradiance of the surface each cell of `reprojection`'s grid looks at (see the
/// module documentation), under `ambient` (luminance) and `lights` (intensities as the fit gives
/// them). `depth` (metres along the optical axis) and `normals` (unit, camera frame; zero =
/// unknown) are the rasters the reprojection marched; a seen cell whose pixel has no valid depth
/// or normal is shaded as a stand-in. `up` (unit, camera frame) tells the walls and ceiling seen
/// above the point, whose median distance places the stand-ins.
///
/// # Errors
/// `SizeMismatch` when the depth or normals are not the photo's size; `InvalidArgument` for a
/// negative or non-finite ambient or an invalid light.
pub(crate) fn proxy_shading(
    reprojection: &PhotoReprojection,
    depth: &Raster<f32>,
    normals: &Raster<[f32; 3]>,
    camera: &Camera,
    up: Vec3,
    ambient: f32,
    lights: &[Light],
) -> Result<Raster<f32>> {
    check_same("normal map", depth, normals)?;
    let photo_size = (depth.width(), depth.height());
    if photo_size != reprojection.photo_size() {
        return Err(Error::SizeMismatch(format!(
            "depth is {}x{} but the reprojection was marched over a {}x{} photo",
            photo_size.0,
            photo_size.1,
            reprojection.photo_size().0,
            reprojection.photo_size().1
        )));
    }
    if !(ambient.is_finite() && ambient >= 0.0) {
        return Err(Error::invalid(format!(
            "shading ambient must be finite and >= 0, got {ambient}"
        )));
    }
    for l in lights {
        l.validate()?;
    }
    let point = reprojection.point();
    let (ew, eh) = reprojection.cells();
    // The surface a cell sees: the depth map's where the photo shows it.
    let seen: Vec<Option<(Vec3, Vec3)>> = reprojection
        .hits()
        .par_iter()
        .map(|hit| {
            let (px, py) = (*hit)?;
            let (px, py) = (px as usize, py as usize);
            let n = Vec3::from(*normals.get(px, py));
            if !n.is_finite() || n.length() < 0.5 {
                return None;
            }
            let p = camera.unproject(px as f32 + 0.5, py as f32 + 0.5, *depth.get(px, py))?;
            Some((p, n.normalize()))
        })
        .collect();
    // Stand-ins replace walls and ceilings: as far as the seen surfaces above the point's
    // horizon (a table just below the point is centimetres away), else as any seen surface.
    let distances = |above: bool| -> Vec<f32> {
        seen.iter()
            .flatten()
            .filter(|(p, _)| !above || (*p - point).dot(up) > 0.0)
            .map(|(p, _)| (*p - point).length())
            .filter(|d| d.is_finite())
            .collect()
    };
    let mut distances = Some(distances(true))
        .filter(|d| !d.is_empty())
        .unwrap_or_else(|| distances(false));
    let proxy_distance = if distances.is_empty() {
        1.0
    } else {
        let mid = distances.len() / 2;
        *distances.select_nth_unstable_by(mid, f32::total_cmp).1
    };
    let shading = seen
        .par_iter()
        .enumerate()
        .map(|(i, surface)| {
            let (p, n) = surface.unwrap_or_else(|| {
                let d = equirect_direction(
                    ((i % ew) as f32 + 0.5) / ew as f32,
                    ((i / ew) as f32 + 0.5) / eh as f32,
                );
                (point + d * proxy_distance, -d)
            });
            let lit: f32 = lights
                .iter()
                .map(|l| luminance(l.intensity) / std::f32::consts::PI * l.unshadowed_term(p, n))
                .sum();
            // A light of finite but huge intensity next to a proxy may overflow; the fill caps
            // how far a cell is relit anyway.
            (ambient + lit).min(f32::MAX)
        })
        .collect();
    Ok(Raster::from_vec(ew, eh, shading))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::light::model::LightKind;
    use std::f32::consts::PI;

    /// A floor 0.5 m below the camera, seen in the lower half of a 120 × 90 view; sky (no
    /// depth) above. Normals up on the floor, unknown elsewhere.
    fn floor() -> (Camera, Raster<f32>, Raster<[f32; 3]>) {
        let camera = Camera::from_focal(60.0, 120, 90).unwrap();
        let depth = Raster::from_fn(120, 90, |x, y| {
            let d = camera.ray_direction(x as f32 + 0.5, y as f32 + 0.5);
            if d.y < 0.0 {
                -d.z * (-0.5 / d.y)
            } else {
                f32::NAN
            }
        });
        let normals = Raster::from_fn(120, 90, |x, y| {
            if depth.get(x, y).is_finite() {
                [0.0, 1.0, 0.0]
            } else {
                [0.0; 3]
            }
        });
        (camera, depth, normals)
    }

    /// The shading of the cell looking along `d`.
    fn at(shading: &Raster<f32>, d: Vec3) -> f32 {
        let (u, v) = super::super::environment::equirect_position(d.normalize());
        let (w, h) = (shading.width(), shading.height());
        *shading.get(
            ((u * w as f32) as usize).min(w - 1),
            ((v * h as f32) as usize).min(h - 1),
        )
    }

    #[test]
    fn seen_surfaces_and_stand_ins_are_shaded_by_the_fitted_lights() {
        let (camera, depth, normals) = floor();
        let point = Vec3::new(0.0, -0.3, -2.0);
        let reprojection = PhotoReprojection::new(
            &normals.map(|_| [0.5f32; 3]),
            Some(&depth),
            &camera,
            point,
            16,
        )
        .unwrap();
        // Straight down from above, irradiance 2 (intensity 2π), ambient 0.5.
        let sun = Light::directional([0.0, -1.0, 0.0], 1.0, [2.0 * PI; 3]);
        let shading = proxy_shading(
            &reprojection,
            &depth,
            &normals,
            &camera,
            Vec3::Y,
            0.5,
            &[sun],
        )
        .unwrap();
        // The floor below the point faces the sun; the stand-in ceiling above it faces away.
        let down = at(&shading, Vec3::new(0.0, -1.0, -0.3));
        let up = at(&shading, Vec3::new(0.0, 1.0, 0.3));
        assert!((down - 2.5).abs() < 1e-3, "floor {down}");
        assert!((up - 0.5).abs() < 1e-6, "ceiling {up}");
        // A lamp hanging 0.15 m above the point lights the stand-in ceiling it is near (the
        // stand-ins are as far as the median seen surface, here the floor: about 0.28 m), more
        // than the stand-in walls farther from it, and the floor below by 1/r².
        let lamp = Light {
            kind: LightKind::Point,
            position: (point + Vec3::Y * 0.15).to_array(),
            direction: [0.0, -1.0, 0.0],
            size: 0.05,
            intensity: [PI; 3],
            confidence: 1.0,
        };
        let shading = proxy_shading(
            &reprojection,
            &depth,
            &normals,
            &camera,
            Vec3::Y,
            0.0,
            &[lamp],
        )
        .unwrap();
        let ceiling = at(&shading, Vec3::Y);
        let wall_behind = at(&shading, Vec3::new(0.0, 0.2, 1.0));
        let floor_below = at(&shading, -Vec3::Y);
        assert!(
            ceiling > 2.0 * wall_behind && wall_behind > 0.0,
            "{ceiling} {wall_behind}"
        );
        // The floor point straight below lies 0.2 + 0.15 m under the lamp (the cell and the
        // pixel it meets are a few centimetres off).
        let want = 1.0 / 0.35f32.powi(2);
        assert!(
            (floor_below - want).abs() < 0.08 * want,
            "floor {floor_below}"
        );
        assert!(shading.pixels().iter().all(|s| s.is_finite() && *s >= 0.0));
        // A light of the largest finite intensity next to a stand-in stays finite.
        let blinding = Light {
            intensity: [f32::MAX; 3],
            ..lamp
        };
        let shading = proxy_shading(
            &reprojection,
            &depth,
            &normals,
            &camera,
            Vec3::Y,
            1.0,
            &[blinding],
        )
        .unwrap();
        assert!(shading.pixels().iter().all(|s| s.is_finite() && *s >= 1.0));
    }

    #[test]
    fn shading_checks_its_inputs() {
        let (camera, depth, normals) = floor();
        let photo = normals.map(|_| [0.5f32; 3]);
        let reprojection =
            PhotoReprojection::new(&photo, Some(&depth), &camera, Vec3::new(0.0, 0.0, -1.0), 8)
                .unwrap();
        let shade =
            |depth: &Raster<f32>, normals: &Raster<[f32; 3]>, ambient: f32, lights: &[Light]| {
                proxy_shading(
                    &reprojection,
                    depth,
                    normals,
                    &camera,
                    Vec3::Y,
                    ambient,
                    lights,
                )
            };
        let no_normals = Raster::filled(4, 4, [0.0f32; 3]);
        assert!(matches!(
            shade(&Raster::filled(4, 4, 1.0f32), &no_normals, 0.1, &[]),
            Err(Error::SizeMismatch(_))
        ));
        assert!(matches!(
            shade(&depth, &no_normals, 0.1, &[]),
            Err(Error::SizeMismatch(_))
        ));
        for ambient in [f32::NAN, -1.0, f32::INFINITY] {
            let err = shade(&depth, &normals, ambient, &[]).unwrap_err();
            assert!(err.to_string().contains("ambient"), "{err}");
        }
        let bad = Light::directional([0.0, -1.0, 0.0], 1.0, [f32::NAN; 3]);
        assert!(shade(&depth, &normals, 0.1, &[bad]).is_err());
        // Without lights every surface gets the ambient.
        let shading = shade(&depth, &normals, 0.25, &[]).unwrap();
        assert_eq!(shading.width(), 32);
        assert!(shading.pixels().iter().all(|s| *s == 0.25));
    }
}
