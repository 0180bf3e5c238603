//! Which pixels of a depth map the matcher filled rather than measured, read from the depth's
//! confidence (the stereo matcher's, 0 on the holes it filled and where it had nothing to match,
//! or a host's). Placement and the snapping of mesh normals both trust a plane over such depth
//! (docs/reconstruction-eval.md, stops 47 and 48).

use glam::Vec2;

use crate::camera::Camera;
use crate::image::Raster;

/// A confidence map that belongs to a camera's image: a pixel of confidence 0 (or less) was
/// filled.
#[derive(Debug, Clone, Copy)]
pub(crate) struct FilledDepth<'a> {
    confidence: &'a Raster<f32>,
}

impl<'a> FilledDepth<'a> {
    /// The map, when it has the camera's size. A map of another size says nothing about this
    /// camera's pixels, so every depth then counts as measured (`None`).
    pub(crate) fn for_camera(confidence: Option<&'a Raster<f32>>, camera: &Camera) -> Option<Self> {
        let size = (camera.width as usize, camera.height as usize);
        confidence
            .filter(|c| (c.width(), c.height()) == size)
            .map(|confidence| Self { confidence })
    }

    /// Whether the depth of the pixel holding `pixel` (continuous pixel coordinates) was filled.
    /// A position outside the image is clamped onto its edge: a UV of exactly 1 (the image's far
    /// edge) maps onto the last pixel.
    pub(crate) fn at(&self, pixel: Vec2) -> bool {
        let c = self.confidence;
        let x = (pixel.x.max(0.0) as usize).min(c.width() - 1);
        let y = (pixel.y.max(0.0) as usize).min(c.height() - 1);
        *c.get(x, y) <= 0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera(width: u32, height: u32) -> Camera {
        Camera::new(
            100.0,
            100.0,
            width as f32 / 2.0,
            height as f32 / 2.0,
            width,
            height,
        )
        .unwrap()
    }

    #[test]
    fn a_pixel_of_confidence_zero_was_filled_and_the_edges_clamp() {
        let confidence = Raster::from_fn(4, 3, |x, y| if (x, y) == (3, 2) { 0.0 } else { 0.7 });
        let filled = FilledDepth::for_camera(Some(&confidence), &camera(4, 3)).unwrap();
        assert!(filled.at(Vec2::new(3.5, 2.5)));
        assert!(!filled.at(Vec2::new(2.5, 2.5)));
        // The far corner (UV 1, 1) and beyond it land on the last pixel; the near side on the first.
        assert!(filled.at(Vec2::new(4.0, 3.0)));
        assert!(filled.at(Vec2::new(9.0, 7.0)));
        assert!(!filled.at(Vec2::new(-1.0, -1.0)));
    }

    #[test]
    fn a_map_of_another_size_or_none_tells_nothing() {
        let confidence = Raster::from_fn(4, 3, |_, _| 0.0f32);
        assert!(FilledDepth::for_camera(Some(&confidence), &camera(3, 4)).is_none());
        assert!(FilledDepth::for_camera(None, &camera(4, 3)).is_none());
        assert!(FilledDepth::for_camera(Some(&confidence), &camera(4, 3)).is_some());
    }
}
