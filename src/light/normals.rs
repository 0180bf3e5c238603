//! Per-pixel surface normals from a depth map, for estimators that get depth but no normals.

use glam::Vec3;

use super::filters::check_size;
use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::image::Raster;

/// Unit normals (camera frame, facing the camera) from central differences of the unprojected
/// depth; a neighbour more than `max_depth_step` (relative) away counts as across an edge and the
/// one-sided difference is used instead. Zero where no normal can be formed.
///
/// # Errors
/// `SizeMismatch` when the depth map is not the camera's size; `InvalidArgument` for an empty map,
/// a bad camera or a threshold that is not finite and > 0.
pub fn normals_from_depth(
    depth: &Raster<f32>,
    camera: &Camera,
    max_depth_step: f32,
) -> Result<Raster<[f32; 3]>> {
    let (w, h) = check_size("depth map", depth)?;
    camera.validate()?;
    if (w, h) != (camera.width as usize, camera.height as usize) {
        return Err(Error::SizeMismatch(format!(
            "depth map is {w}x{h} but the camera's image is {}x{}",
            camera.width, camera.height
        )));
    }
    if !(max_depth_step.is_finite() && max_depth_step > 0.0) {
        return Err(Error::invalid(format!(
            "max_depth_step must be finite and > 0, got {max_depth_step}"
        )));
    }
    let point =
        |x: usize, y: usize| camera.unproject(x as f32 + 0.5, y as f32 + 0.5, *depth.get(x, y));
    Ok(Raster::from_fn(w, h, |x, y| {
        let Some(p) = point(x, y) else {
            return [0.0; 3];
        };
        let near = |q: Option<Vec3>| q.filter(|q| (q.z - p.z).abs() <= max_depth_step * -p.z);
        let side = |a: Option<Vec3>, b: Option<Vec3>| match (near(a), near(b)) {
            (Some(a), Some(b)) => Some(b - a),
            (Some(a), None) => Some(p - a),
            (None, Some(b)) => Some(b - p),
            (None, None) => None,
        };
        let dx = side(
            (x > 0).then(|| point(x - 1, y)).flatten(),
            (x + 1 < w).then(|| point(x + 1, y)).flatten(),
        );
        let dy = side(
            (y > 0).then(|| point(x, y - 1)).flatten(),
            (y + 1 < h).then(|| point(x, y + 1)).flatten(),
        );
        let (Some(dx), Some(dy)) = (dx, dy) else {
            return [0.0; 3];
        };
        // x grows right and image y grows down, so dy × dx faces the camera (+Z).
        let n = dy.cross(dx).normalize_or_zero();
        let n = if n.dot(-p) < 0.0 { -n } else { n };
        if n.is_finite() {
            n.to_array()
        } else {
            [0.0; 3]
        }
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_floor_plane_has_an_up_normal() {
        // The plane y = −1 seen by a level camera: depth at row v is f / (v − cy) below the horizon.
        let camera = Camera::from_focal(100.0, 64, 48).unwrap();
        let depth = Raster::from_fn(64, 48, |_, y| {
            let dv = y as f32 + 0.5 - camera.cy;
            if dv > 0.5 {
                camera.fy / dv
            } else {
                f32::NAN
            }
        });
        let n = normals_from_depth(&depth, &camera, 0.2).unwrap();
        let v = Vec3::from(*n.get(30, 40));
        assert!(v.abs_diff_eq(Vec3::Y, 1e-3), "{v}");
        assert_eq!(*n.get(30, 5), [0.0; 3]);
        assert!(normals_from_depth(&depth, &camera, 0.0).is_err());
        assert!(normals_from_depth(&Raster::filled(3, 3, 1.0), &camera, 0.1).is_err());
    }
}
