//! Light sources seen in the photo (thesis §3.3.4): bright pixels grouped into blobs, each a light
//! with a 3D position, size, colour and intensity: a disc where the blob is a flat panel, a
//! sphere where it is a bulb (its normals spread) or has no depth of its own.
//!
//! Bright means saturated in an LDR photo (the largest channel ≥ `saturation`) and, in an HDR photo
//! (some pixel above 1.0, the photo's white), a luminance of at least `hdr_fraction` of the
//! brightest pixel (robust maximum) and above 1.0.
//!
//! Not every bright blob emits. A blob is rejected as a non-emitter when
//! - it is smaller than `min_pixels` (specular glints on glossy objects, noise);
//! - it covers more than `max_area_fraction` of the image (an over-exposed white surface or sky);
//! - it is not at least `min_contrast` times brighter than a ring of pixels around it (a lit
//!   white wall is about as bright as its surroundings; a lamp is much brighter than its own
//!   surroundings, since light falls off with distance from it);
//! - its surface, where depth is known, faces up (normal · up > 0.8): an emitter on a floor or
//!   table top is far less likely than the mirror reflection of a ceiling lamp on it.

use glam::Vec3;

use super::filters::{check_photo_camera, check_same, components, luminance};
use super::model::{Light, LightKind};
use super::normals::normals_from_depth;
use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::image::Raster;

/// Options of [`detect_sources`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SourceOptions {
    /// LDR: a pixel whose largest channel reaches this is saturated, in (0, 1].
    pub saturation: f32,
    /// HDR: bright pixels have at least this fraction of the robust maximum luminance, in (0, 1].
    pub hdr_fraction: f32,
    /// Smallest blob, pixels (≥ 1).
    pub min_pixels: usize,
    /// Largest blob as a fraction of the image, in (0, 1].
    pub max_area_fraction: f32,
    /// How much brighter than its surroundings a blob must be (≥ 1).
    pub min_contrast: f32,
    /// Gravity up in the camera frame (for the floor-reflection test).
    pub up: [f32; 3],
    /// Distance at which lights without depth are put on their pixel ray, metres (> 0); the
    /// camera's far plane when it is nearer.
    pub missing_depth_m: f32,
    /// At most this many lights, brightest first.
    pub max_lights: usize,
}

impl Default for SourceOptions {
    fn default() -> Self {
        SourceOptions {
            saturation: 0.98,
            hdr_fraction: 0.2,
            min_pixels: 6,
            max_area_fraction: 0.2,
            min_contrast: 2.5,
            up: [0.0, 1.0, 0.0],
            missing_depth_m: 20.0,
            max_lights: 8,
        }
    }
}

impl SourceOptions {
    /// Checks ranges.
    ///
    /// # Errors
    /// `InvalidArgument` naming the option out of range.
    pub fn validate(&self) -> Result<()> {
        let unit = |name: &str, v: f32| {
            if v > 0.0 && v <= 1.0 {
                Ok(())
            } else {
                Err(Error::invalid(format!(
                    "source {name} must be in (0, 1], got {v}"
                )))
            }
        };
        unit("saturation", self.saturation)?;
        unit("hdr_fraction", self.hdr_fraction)?;
        unit("max_area_fraction", self.max_area_fraction)?;
        if self.min_pixels == 0 {
            return Err(Error::invalid("source min_pixels must be >= 1"));
        }
        if !(self.min_contrast >= 1.0 && self.min_contrast.is_finite()) {
            return Err(Error::invalid(format!(
                "source min_contrast must be finite and >= 1, got {}",
                self.min_contrast
            )));
        }
        if !(self.missing_depth_m.is_finite() && self.missing_depth_m > 0.0) {
            return Err(Error::invalid(format!(
                "source missing_depth_m must be finite and > 0, got {}",
                self.missing_depth_m
            )));
        }
        let up = Vec3::from(self.up);
        if !up.is_finite() || up.length() < 1e-6 {
            return Err(Error::invalid(format!(
                "source up must be a finite non-zero vector, got {:?}",
                self.up
            )));
        }
        Ok(())
    }
}

/// Least length of a blob's mean unit normal for it to be a flat emitter (a disc); below it (a
/// bulb: 2/3 over the visible half of a sphere) or without the blob's own depth it is a sphere.
const PANEL_COHERENCE: f32 = 0.9;

/// The bright pixels of a photo (see the module documentation): in an LDR photo those whose
/// largest channel reaches `saturation`; in an HDR one (robust maximum luminance above 1.0) those
/// above 1.0 with at least `hdr_fraction` of the robust maximum.
pub(crate) fn bright_pixels(
    photo: &Raster<[f32; 3]>,
    saturation: f32,
    hdr_fraction: f32,
) -> Raster<bool> {
    let luma = photo.map(|c| luminance(*c));
    // Robust maximum: ignores a handful of hot pixels. A selection, not a sort: this runs on
    // every environment built from a photo.
    let mut values: Vec<f32> = luma.pixels().to_vec();
    let robust_max = if values.is_empty() {
        0.0
    } else {
        let rank = ((values.len() - 1) as f64 * 0.9995) as usize;
        *values.select_nth_unstable_by(rank, f32::total_cmp).1
    };
    if robust_max > 1.0 {
        luma.map(|y| *y > 1.0 && *y >= hdr_fraction * robust_max)
    } else {
        let clean = |v: f32| if v.is_finite() { v.max(0.0) } else { 0.0 };
        photo.map(|c| c.iter().fold(0.0f32, |m, v| m.max(clean(*v))) >= saturation)
    }
}

/// Finds the light sources visible in a linear RGB photo.
///
/// `depth` (metres along the optical axis, NaN/inf = unknown) places each light; without depth, or
/// where a blob and its surroundings have none, the light goes on its pixel ray at
/// `missing_depth_m` (or the far plane) with half the confidence. A blob whose own depth is measured
/// and whose normals agree (a ceiling panel, a screen) becomes an [`LightKind::Area`] disc facing
/// away from that surface; any other blob (a bulb, whose normals spread over a sphere, or a blob
/// without its own depth) becomes a [`LightKind::Point`] sphere that emits every way: with its
/// own depth, centred a radius behind its median depth, else where a disc would be. Either way
/// the diameter matches the blob's area at that depth and the radiant intensity is
/// `mean radiance × that area`. A saturated LDR blob only gives a lower bound of its radiance;
/// [`crate::light::fit_lights`] rescales in-view lights from the shading they cause.
///
/// # Errors
/// `InvalidArgument` for an empty photo, bad options or camera; `SizeMismatch` when the depth map
/// or the camera is not the photo's size.
pub fn detect_sources(
    photo: &Raster<[f32; 3]>,
    depth: Option<&Raster<f32>>,
    camera: &Camera,
    options: &SourceOptions,
) -> Result<Vec<Light>> {
    options.validate()?;
    camera.validate()?;
    let (w, h) = check_photo_camera(photo, camera)?;
    if let Some(d) = depth {
        check_same("depth map", photo, d)?;
    }
    let bright = bright_pixels(photo, options.saturation, options.hdr_fraction);
    let luma = photo.map(|c| luminance(*c));
    let clean = |c: [f32; 3]| c.map(|v| if v.is_finite() { v.max(0.0) } else { 0.0 });
    let (label, groups) = components(w, h, |x, y| *bright.get(x, y));
    let normals = match depth {
        Some(d) => Some(normals_from_depth(d, camera, 0.05)?),
        None => None,
    };
    let up = Vec3::from(options.up).normalize();
    let mut lights = Vec::new();
    for (id, group) in groups.iter().enumerate() {
        if group.len() < options.min_pixels
            || group.len() as f32 > options.max_area_fraction * (w * h) as f32
        {
            continue;
        }
        // Ring: pixels within a margin of the blob's bounding box that are not in the blob.
        let (mut x0, mut y0, mut x1, mut y1) = (w, h, 0, 0);
        for &(x, y) in group {
            (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
        }
        let margin = ((group.len() as f32).sqrt() as usize / 2).max(2);
        let (rx0, ry0) = (x0.saturating_sub(margin), y0.saturating_sub(margin));
        let (rx1, ry1) = ((x1 + margin).min(w - 1), (y1 + margin).min(h - 1));
        let (mut ring, mut ring_n) = (0.0f64, 0usize);
        let mut ring_depths = Vec::new();
        for y in ry0..=ry1 {
            for x in rx0..=rx1 {
                if label[y * w + x] != id as u32 {
                    ring += *luma.get(x, y) as f64;
                    ring_n += 1;
                    if let Some(z) = depth
                        .map(|d| *d.get(x, y))
                        .filter(|z| z.is_finite() && *z > 0.0)
                    {
                        ring_depths.push(z);
                    }
                }
            }
        }
        let mut radiance = [0.0f64; 3];
        let (mut cu, mut cv) = (0.0f64, 0.0f64);
        let mut depths = Vec::new();
        let mut normal_sum = Vec3::ZERO;
        let mut normal_count = 0usize;
        for &(x, y) in group {
            let c = clean(*photo.get(x, y));
            for k in 0..3 {
                radiance[k] += c[k] as f64;
            }
            cu += x as f64 + 0.5;
            cv += y as f64 + 0.5;
            if let Some(z) = depth
                .map(|d| *d.get(x, y))
                .filter(|z| z.is_finite() && *z > 0.0)
            {
                depths.push(z);
            }
            if let Some(n) = &normals {
                let normal = Vec3::from(*n.get(x, y));
                if normal.length() > 0.5 {
                    normal_sum += normal;
                    normal_count += 1;
                }
            }
        }
        let n = group.len() as f64;
        let radiance = radiance.map(|v| (v / n) as f32);
        let blob_luma = luminance(radiance);
        let ring_luma = if ring_n > 0 {
            (ring / ring_n as f64) as f32
        } else {
            0.0
        };
        if blob_luma < options.min_contrast * ring_luma {
            continue;
        }
        let surface_normal = normal_sum.normalize_or_zero();
        if surface_normal.dot(up) > 0.8 {
            continue;
        }
        let (u, v) = ((cu / n) as f32, (cv / n) as f32);
        let median = |mut values: Vec<f32>| {
            let mid = values.len() / 2;
            values.select_nth_unstable_by(mid, f32::total_cmp);
            values[mid]
        };
        let own_depth = depths.len() * 4 >= group.len();
        let (z, confidence) = if own_depth {
            (median(depths), 0.8)
        } else if !ring_depths.is_empty() {
            // Saturated blobs often have no stereo depth: the lamp sits on what surrounds it.
            (median(ring_depths), 0.6)
        } else {
            (options.missing_depth_m.min(camera.far), 0.4)
        };
        let Some(position) = camera.unproject(u, v, z) else {
            continue;
        };
        // Pixel footprint at depth z: the disc of the blob's area.
        let area_m2 = n as f32 * (z / camera.fx) * (z / camera.fy);
        let diameter = 2.0 * (area_m2 / std::f32::consts::PI).sqrt();
        // A flat emitter's pixels share one normal; a bulb's spread over the visible half of a
        // sphere, whose mean unit normal (pixels weigh by projected area) has length 2/3.
        let coherence = if normal_count > 0 {
            normal_sum.length() / normal_count as f32
        } else {
            0.0
        };
        let light = if own_depth && coherence >= PANEL_COHERENCE {
            Light {
                kind: LightKind::Area,
                position: position.to_array(),
                direction: surface_normal.to_array(),
                size: diameter,
                intensity: radiance.map(|l| l * area_m2),
                confidence,
            }
        } else {
            // A bulb (or a blob whose own depth is unknown): a sphere that emits every way. Its
            // measured depth is on its visible surface, so the centre lies a radius further along
            // the pixel's ray. (The median of that surface is a little behind its front; the
            // nearest depths are the stereo's least reliable on a saturated blob, so the median
            // is kept.)
            let centre = if own_depth {
                position + position.normalize_or_zero() * diameter / 2.0
            } else {
                position
            };
            Light {
                kind: LightKind::Point,
                position: centre.to_array(),
                direction: (-up).to_array(),
                size: diameter,
                intensity: radiance.map(|l| l * area_m2),
                confidence,
            }
        };
        if light.validate().is_ok() {
            lights.push(light);
        }
    }
    lights.sort_by(|a, b| luminance(b.intensity).total_cmp(&luminance(a.intensity)));
    lights.truncate(options.max_lights);
    Ok(lights)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera::from_focal(100.0, 120, 90).unwrap()
    }

    /// A dim wall at 3 m with a bright 10×10 px lamp at (30..40, 20..30) and a 3 px glint.
    fn wall_with_lamp(lamp: [f32; 3]) -> (Raster<[f32; 3]>, Raster<f32>) {
        let photo = Raster::from_fn(120, 90, |x, y| {
            if (30..40).contains(&x) && (20..30).contains(&y) {
                lamp
            } else if (80..83).contains(&x) && y == 60 {
                [1.0; 3]
            } else {
                [0.2, 0.18, 0.15]
            }
        });
        (photo, Raster::filled(120, 90, 3.0))
    }

    #[test]
    fn a_flat_lamp_becomes_one_area_light_at_its_depth() {
        let (photo, depth) = wall_with_lamp([1.0; 3]);
        let lights = detect_sources(&photo, Some(&depth), &camera(), &Default::default()).unwrap();
        assert_eq!(lights.len(), 1, "{lights:?}");
        let l = lights[0];
        assert_eq!(l.kind, LightKind::Area);
        let expected = camera().unproject(35.0, 25.0, 3.0).unwrap();
        assert!(Vec3::from(l.position).distance(expected) < 1e-3, "{l:?}");
        // 100 px at 3 m with f = 100: 0.09 m², a disc of diameter 2·√(0.09/π).
        assert!((l.size - 2.0 * (0.09f32 / std::f32::consts::PI).sqrt()).abs() < 1e-3);
        assert!((l.intensity[0] - 0.09).abs() < 1e-4);
        // The wall faces the camera, so the disc emits towards it.
        assert!(Vec3::from(l.direction).abs_diff_eq(Vec3::Z, 1e-3));
    }

    #[test]
    fn a_bulb_becomes_a_sphere_centred_behind_its_visible_surface() {
        // A wall at 3 m and a bulb of radius 0.15 m centred 2.5 m away on the optical axis.
        let cam = camera();
        let centre = Vec3::new(0.0, 0.0, -2.5);
        let radius = 0.15f32;
        let hit = |x: usize, y: usize| {
            let d = cam.ray_direction(x as f32 + 0.5, y as f32 + 0.5);
            let (a, b) = (d.length_squared(), d.dot(centre));
            let disc = b * b - a * (centre.length_squared() - radius * radius);
            (disc >= 0.0).then(|| -(d * (b - disc.sqrt()) / a).z)
        };
        let photo = Raster::from_fn(120, 90, |x, y| {
            if hit(x, y).is_some() {
                [1.0; 3]
            } else {
                [0.2, 0.18, 0.15]
            }
        });
        let depth = Raster::from_fn(120, 90, |x, y| hit(x, y).unwrap_or(3.0));
        let lights = detect_sources(&photo, Some(&depth), &cam, &Default::default()).unwrap();
        assert_eq!(lights.len(), 1, "{lights:?}");
        let l = lights[0];
        assert_eq!(l.kind, LightKind::Point, "{l:?}");
        // The blob's median depth lies a little behind its front (2.35 m) and its area gives a
        // diameter a little small, so the centre lands within 4 cm of the sphere's.
        assert!(Vec3::from(l.position).distance(centre) < 0.04, "{l:?}");
        assert!((l.size - 2.0 * radius).abs() < 0.04, "{l:?}");
    }

    #[test]
    fn hdr_lamp_without_depth_goes_to_the_far_distance() {
        let (photo, _) = wall_with_lamp([500.0, 400.0, 300.0]);
        let lights = detect_sources(&photo, None, &camera(), &Default::default()).unwrap();
        assert_eq!(lights.len(), 1);
        // Nothing says it is flat: a sphere.
        assert_eq!(lights[0].kind, LightKind::Point);
        assert!((-lights[0].position[2] - 20.0).abs() < 1e-3);
        assert!(lights[0].intensity[0] > lights[0].intensity[2]);
    }

    #[test]
    fn white_walls_floor_glints_and_saturated_images_are_not_lights() {
        // A bright wall barely brighter than its surroundings.
        let photo = Raster::from_fn(120, 90, |x, _| if x < 60 { [1.0; 3] } else { [0.8; 3] });
        assert!(detect_sources(&photo, None, &camera(), &Default::default())
            .unwrap()
            .is_empty());
        // Everything saturated.
        let photo = Raster::filled(120, 90, [1.0f32; 3]);
        assert!(detect_sources(&photo, None, &camera(), &Default::default())
            .unwrap()
            .is_empty());
        // A lamp-like blob on a floor (depth of a plane below a level camera): a reflection.
        let cam = camera();
        let depth = Raster::from_fn(120, 90, |_, y| {
            let dv = y as f32 + 0.5 - cam.cy;
            if dv > 0.5 {
                cam.fy / dv
            } else {
                f32::NAN
            }
        });
        let photo = Raster::from_fn(120, 90, |x, y| {
            if (50..60).contains(&x) && (70..78).contains(&y) {
                [1.0; 3]
            } else {
                [0.1; 3]
            }
        });
        assert!(
            detect_sources(&photo, Some(&depth), &cam, &Default::default())
                .unwrap()
                .is_empty()
        );
    }

    #[test]
    fn extreme_input_is_finite_and_bad_input_named() {
        let cam = Camera::from_focal(1.0, 1, 1).unwrap();
        for v in [0.0, 1.0, 1e6, f32::NAN, f32::INFINITY, -5.0] {
            let photo = Raster::filled(1, 1, [v; 3]);
            for l in detect_sources(&photo, None, &cam, &Default::default()).unwrap() {
                l.validate().unwrap();
            }
        }
        let photo = Raster::from_fn(
            120,
            90,
            |x, y| if x == 5 && y == 5 { [1e6; 3] } else { [0.1; 3] },
        );
        let options = SourceOptions {
            min_pixels: 1,
            ..Default::default()
        };
        let lights = detect_sources(&photo, None, &camera(), &options).unwrap();
        assert_eq!(lights.len(), 1);
        lights[0].validate().unwrap();
        let e = detect_sources(
            &Raster::filled(5, 5, [0.0; 3]),
            None,
            &camera(),
            &Default::default(),
        )
        .unwrap_err();
        assert!(e.to_string().contains("photo"));
        let e = detect_sources(
            &Raster::filled(120, 90, [0.0; 3]),
            Some(&Raster::filled(4, 4, 1.0)),
            &camera(),
            &Default::default(),
        )
        .unwrap_err();
        assert!(e.to_string().contains("depth"));
        let bad = SourceOptions {
            min_contrast: 0.5,
            ..Default::default()
        };
        assert!(detect_sources(&photo, None, &camera(), &bad).is_err());
    }
}
