//! Where the photo already has cast shadows: a soft mask in [0, 1] (1 = in shadow).
//!
//! Two methods, selected by [`ShadowMethod`]:
//! - [`ShadowMethod::Thesis`] — the thesis' Algorithm 5 (Appendix B.2): luminance, histogram
//!   equalisation, a 31-pixel sliding-window average compared with the full-image average, a
//!   median filter, and an edge test that drops dark regions with a sharp (object-like) border.
//!   Binary (0 or 1).
//! - [`ShadowMethod::Chromaticity`] (default) — a pixel is in shadow when it is darker than the
//!   lit part of its own surface nearby while keeping that surface's chromaticity: shading
//!   changes brightness, not colour, whereas a dark object of another material changes both. The
//!   "lit part" is the mean of the brighter half of a large window, counting only pixels of the
//!   same continuous region (from [`continuity_regions`]) when regions are given, so the edge of
//!   a dark object that sits on a bright one does not compare the two.
//!
//! The mask is used later so that an inserted object does not darken a second time where the photo
//! already shows a shadow.

use std::collections::HashMap;

use glam::Vec3;

use super::filters::{box_mean, check_same, check_size, components, luminance, median};
use crate::error::{Error, Result};
use crate::image::{linear_to_srgb, Raster};

/// Which shadow detector to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ShadowMethod {
    /// The thesis' Algorithm 5 (binary).
    Thesis,
    /// Darker than the lit part of the same surface with unchanged chromaticity (soft).
    #[default]
    Chromaticity,
}

/// Options of [`shadow_mask`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShadowOptions {
    /// The detector.
    pub method: ShadowMethod,
    /// Thesis: the sliding window's edge length, pixels (the thesis uses 31; odd, ≥ 3).
    pub window: usize,
    /// Chromaticity: brightness ratio (pixel / lit neighbourhood) at or above which a pixel is
    /// fully lit, in (0, 1].
    pub lit_ratio: f32,
    /// Chromaticity: ratio at or below which a pixel is fully in shadow, in [0, `lit_ratio`).
    pub shadow_ratio: f32,
    /// Chromaticity: largest change of chromaticity (r, g, b divided by their sum) a shadow may
    /// bring; twice this rejects the pixel entirely.
    pub chroma_tolerance: f32,
}

impl Default for ShadowOptions {
    fn default() -> Self {
        ShadowOptions {
            method: ShadowMethod::Chromaticity,
            window: 31,
            lit_ratio: 0.8,
            shadow_ratio: 0.45,
            chroma_tolerance: 0.05,
        }
    }
}

impl ShadowOptions {
    /// Checks ranges.
    ///
    /// # Errors
    /// `InvalidArgument` naming the option out of range.
    pub fn validate(&self) -> Result<()> {
        if self.window < 3 || self.window.is_multiple_of(2) || self.window > 1001 {
            return Err(Error::invalid(format!(
                "shadow window must be odd and in 3..=1001 pixels, got {}",
                self.window
            )));
        }
        if !(self.lit_ratio > 0.0 && self.lit_ratio <= 1.0) {
            return Err(Error::invalid(format!(
                "shadow lit_ratio must be in (0, 1], got {}",
                self.lit_ratio
            )));
        }
        if !(self.shadow_ratio >= 0.0 && self.shadow_ratio < self.lit_ratio) {
            return Err(Error::invalid(format!(
                "shadow shadow_ratio must be in [0, lit_ratio), got {}",
                self.shadow_ratio
            )));
        }
        if !(self.chroma_tolerance > 0.0 && self.chroma_tolerance.is_finite()) {
            return Err(Error::invalid(format!(
                "shadow chroma_tolerance must be finite and > 0, got {}",
                self.chroma_tolerance
            )));
        }
        Ok(())
    }
}

/// Label of pixels that belong to no region in [`continuity_regions`].
pub const NO_REGION: u32 = u32::MAX;

/// Splits the image into continuous surfaces: 8-connected pixels whose depths differ by less than
/// `max_depth_step` (relative, e.g. 0.03 = 3 %) and, when normals are given, whose normals differ
/// by less than `max_normal_deg`. Pixels without depth get [`NO_REGION`]; so do regions smaller
/// than `min_pixels`.
///
/// # Errors
/// `SizeMismatch` when `normals` is not the depth's size; `InvalidArgument` for an empty map or a
/// non-positive or non-finite threshold.
pub fn continuity_regions(
    depth: &Raster<f32>,
    normals: Option<&Raster<[f32; 3]>>,
    max_depth_step: f32,
    max_normal_deg: f32,
    min_pixels: usize,
) -> Result<Raster<u32>> {
    let (w, h) = check_size("depth map", depth)?;
    if let Some(n) = normals {
        check_same("normal map", depth, n)?;
    }
    if !(max_depth_step.is_finite() && max_depth_step > 0.0) {
        return Err(Error::invalid(format!(
            "max_depth_step must be finite and > 0, got {max_depth_step}"
        )));
    }
    if !(max_normal_deg.is_finite() && max_normal_deg > 0.0) {
        return Err(Error::invalid(format!(
            "max_normal_deg must be finite and > 0, got {max_normal_deg}"
        )));
    }
    let cos_tol = max_normal_deg.to_radians().cos();
    let valid = |x: usize, y: usize| {
        let z = *depth.get(x, y);
        z.is_finite() && z > 0.0
    };
    // Union-find over 4-neighbour links that pass both tests (a flood fill would need the pair
    // test inside the fill, which the shared helper does not take).
    let mut parent: Vec<u32> = (0..(w * h) as u32).collect();
    fn find(parent: &mut [u32], mut i: u32) -> u32 {
        while parent[i as usize] != i {
            parent[i as usize] = parent[parent[i as usize] as usize];
            i = parent[i as usize];
        }
        i
    }
    let linked = |a: (usize, usize), b: (usize, usize)| {
        if !valid(a.0, a.1) || !valid(b.0, b.1) {
            return false;
        }
        let (za, zb) = (*depth.get(a.0, a.1), *depth.get(b.0, b.1));
        if (za - zb).abs() > max_depth_step * za.min(zb) {
            return false;
        }
        match normals {
            Some(n) => {
                let na = Vec3::from(*n.get(a.0, a.1));
                let nb = Vec3::from(*n.get(b.0, b.1));
                na.dot(nb) >= cos_tol * na.length() * nb.length()
            }
            None => true,
        }
    };
    for y in 0..h {
        for x in 0..w {
            for (nx, ny) in [(x + 1, y), (x, y + 1)] {
                if nx < w && ny < h && linked((x, y), (nx, ny)) {
                    let (a, b) = (
                        find(&mut parent, (y * w + x) as u32),
                        find(&mut parent, (ny * w + nx) as u32),
                    );
                    if a != b {
                        parent[a.max(b) as usize] = a.min(b);
                    }
                }
            }
        }
    }
    let mut size = vec![0usize; w * h];
    let roots: Vec<u32> = (0..(w * h) as u32).map(|i| find(&mut parent, i)).collect();
    for (i, r) in roots.iter().enumerate() {
        if valid(i % w, i / w) {
            size[*r as usize] += 1;
        }
    }
    // Renumber the kept regions 0, 1, … in order of first appearance.
    let mut id = vec![NO_REGION; w * h];
    let mut next = 0u32;
    let labels = roots
        .iter()
        .enumerate()
        .map(|(i, r)| {
            if !valid(i % w, i / w) || size[*r as usize] < min_pixels.max(1) {
                return NO_REGION;
            }
            if id[*r as usize] == NO_REGION {
                id[*r as usize] = next;
                next += 1;
            }
            id[*r as usize]
        })
        .collect();
    Ok(Raster::from_vec(w, h, labels))
}

/// A soft shadow mask of a linear RGB photo: 1 where the photo shows a cast shadow, 0 where lit.
///
/// `regions` (from [`continuity_regions`], or a host's segmentation; [`NO_REGION`] = unknown)
/// restricts the chromaticity method's neighbourhood to the pixel's own surface; the thesis
/// method ignores it. Non-finite or negative pixels count as black.
///
/// # Errors
/// `InvalidArgument` for an empty photo or bad options; `SizeMismatch` when `regions` is not the
/// photo's size.
pub fn shadow_mask(
    photo: &Raster<[f32; 3]>,
    regions: Option<&Raster<u32>>,
    options: &ShadowOptions,
) -> Result<Raster<f32>> {
    options.validate()?;
    check_size("photo", photo)?;
    if let Some(r) = regions {
        check_same("region map", photo, r)?;
    }
    match options.method {
        ShadowMethod::Thesis => Ok(thesis_mask(photo, options)),
        ShadowMethod::Chromaticity => Ok(chromaticity_mask(photo, regions, options)),
    }
}

/// Algorithm 5: equalised luma darker than both its window's and the image's average, median
/// filtered; components whose border is as sharp as an object's edge are dropped.
fn thesis_mask(photo: &Raster<[f32; 3]>, options: &ShadowOptions) -> Raster<f32> {
    let (w, h) = (photo.width(), photo.height());
    // 8-bit-like luma (the thesis works on the stored image), then histogram equalisation.
    let luma = photo.map(|c| linear_to_srgb(luminance(*c).min(1.0)));
    let mut hist = [0usize; 256];
    for v in luma.pixels() {
        hist[(v * 255.0).round().clamp(0.0, 255.0) as usize] += 1;
    }
    let mut cdf = [0.0f32; 256];
    let mut acc = 0usize;
    for (i, c) in hist.iter().enumerate() {
        acc += c;
        cdf[i] = acc as f32 / (w * h) as f32;
    }
    let eq = luma.map(|v| cdf[(v * 255.0).round().clamp(0.0, 255.0) as usize]);
    let eq = median(&eq, 2);
    let full_average = eq.pixels().iter().sum::<f32>() / (w * h) as f32;
    let local = box_mean(&eq, None, options.window / 2, full_average);
    let raw = Raster::from_fn(w, h, |x, y| {
        let v = *eq.get(x, y);
        // Darker than its window by a margin and than the picture as a whole.
        if v < 0.8 * *local.get(x, y) && v < full_average {
            1.0
        } else {
            0.0
        }
    });
    let mut mask = median(&raw, 2);
    // Edge test: shadows (penumbrae) have smooth borders, dark objects sharp ones. Sharpness =
    // mean gradient across the border / contrast between the two sides (≈ 1 / edge width, px).
    let grad = Raster::from_fn(w, h, |x, y| {
        let at = |xx: i64, yy: i64| {
            *eq.get(
                xx.clamp(0, w as i64 - 1) as usize,
                yy.clamp(0, h as i64 - 1) as usize,
            )
        };
        let (x, y) = (x as i64, y as i64);
        let gx = (at(x + 1, y) - at(x - 1, y)) / 2.0;
        let gy = (at(x, y + 1) - at(x, y - 1)) / 2.0;
        (gx * gx + gy * gy).sqrt()
    });
    let (label, groups) = components(w, h, |x, y| *mask.get(x, y) > 0.5);
    for (id, group) in groups.iter().enumerate() {
        let (mut g, mut inside, mut outside, mut border) = (0.0f32, 0.0f32, 0.0f32, 0usize);
        let mut n_out = 0usize;
        for &(x, y) in group {
            inside += *eq.get(x, y);
            let mut on_border = false;
            for (dx, dy) in [(-2i64, 0i64), (2, 0), (0, -2), (0, 2)] {
                let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                    continue;
                }
                if label[ny as usize * w + nx as usize] != id as u32 {
                    on_border = true;
                    outside += *eq.get(nx as usize, ny as usize);
                    n_out += 1;
                }
            }
            if on_border {
                g += *grad.get(x, y);
                border += 1;
            }
        }
        if border == 0 || n_out == 0 {
            continue;
        }
        let contrast = outside / n_out as f32 - inside / group.len() as f32;
        let sharpness = (g / border as f32) / contrast.max(1e-3);
        if sharpness > 0.9 {
            for &(x, y) in group {
                *mask.get_mut(x, y) = 0.0;
            }
        }
    }
    mask
}

fn chromaticity_mask(
    photo: &Raster<[f32; 3]>,
    regions: Option<&Raster<u32>>,
    options: &ShadowOptions,
) -> Raster<f32> {
    let (w, h) = (photo.width(), photo.height());
    // Blur a little so texture grain does not read as shading.
    let fine = (w.min(h) / 160).max(1);
    let luma = box_mean(&photo.map(|c| luminance(*c)), None, fine, 0.0);
    let chroma: Vec<Raster<f32>> = (0..3)
        .map(|k| {
            let c = photo.map(|c| {
                let s = |v: f32| if v.is_finite() { v.max(0.0) } else { 0.0 };
                let sum = s(c[0]) + s(c[1]) + s(c[2]);
                if sum > 1e-6 {
                    s(c[k]) / sum
                } else {
                    1.0 / 3.0
                }
            });
            box_mean(&c, None, fine, 1.0 / 3.0)
        })
        .collect();
    let radius = (w.min(h) / 8).max(2);
    let mut lit = Raster::filled(w, h, f32::NAN);
    let mut lit_chroma = vec![Raster::filled(w, h, f32::NAN); 3];
    // One pass per region (and one for pixels of no region, over the whole image), each on the
    // region's bounding box: a photo cut into hundreds of small regions would otherwise cost
    // hundreds of whole-image passes. A region's members weigh only one another, all inside the
    // box; pixels of no region weigh every pixel within `radius`, so their box grows by that.
    let label_at = |x: usize, y: usize| regions.map_or(NO_REGION, |r| *r.get(x, y));
    let mut boxes: HashMap<u32, [usize; 4]> = HashMap::new();
    for y in 0..h {
        for x in 0..w {
            let b = boxes.entry(label_at(x, y)).or_insert([x, y, x, y]);
            *b = [b[0].min(x), b[1].min(y), b[2].max(x), b[3].max(y)];
        }
    }
    let mut labels: Vec<(u32, [usize; 4])> = boxes.into_iter().collect();
    labels.sort_unstable_by_key(|(label, _)| *label);
    for (label, [bx0, by0, bx1, by1]) in labels {
        let margin = if label == NO_REGION { radius } else { 0 };
        let (x0, y0) = (bx0.saturating_sub(margin), by0.saturating_sub(margin));
        let (x1, y1) = ((bx1 + margin + 1).min(w), (by1 + margin + 1).min(h));
        let (cw, ch) = (x1 - x0, y1 - y0);
        let crop = |r: &Raster<f32>| Raster::from_fn(cw, ch, |x, y| *r.get(x0 + x, y0 + y));
        let member = |x: usize, y: usize| label_at(x0 + x, y0 + y) == label;
        let weight = Raster::from_fn(cw, ch, |x, y| {
            if label == NO_REGION || member(x, y) {
                1.0
            } else {
                0.0
            }
        });
        let luma = crop(&luma);
        let mean = box_mean(&luma, Some(&weight), radius, 0.0);
        // The brighter half of the window is taken as the lit surface.
        let bright_weight = Raster::from_fn(cw, ch, |x, y| {
            if *weight.get(x, y) > 0.0 && *luma.get(x, y) >= *mean.get(x, y) {
                1.0
            } else {
                0.0
            }
        });
        let level = box_mean(&luma, Some(&bright_weight), radius, 0.0);
        let hue: Vec<Raster<f32>> = chroma
            .iter()
            .map(|c| box_mean(&crop(c), Some(&bright_weight), radius, 1.0 / 3.0))
            .collect();
        for y in 0..ch {
            for x in 0..cw {
                if member(x, y) {
                    *lit.get_mut(x0 + x, y0 + y) = *level.get(x, y);
                    for k in 0..3 {
                        *lit_chroma[k].get_mut(x0 + x, y0 + y) = *hue[k].get(x, y);
                    }
                }
            }
        }
    }
    let span = options.lit_ratio - options.shadow_ratio;
    let soft = Raster::from_fn(w, h, |x, y| {
        let reference = *lit.get(x, y);
        if !(reference.is_finite() && reference > 1e-6) {
            return 0.0;
        }
        let ratio = *luma.get(x, y) / reference;
        let dark = ((options.lit_ratio - ratio) / span).clamp(0.0, 1.0);
        let shift = (0..3)
            .map(|k| (chroma[k].get(x, y) - lit_chroma[k].get(x, y)).abs())
            .fold(0.0f32, f32::max);
        let same_colour = (2.0 - shift / options.chroma_tolerance).clamp(0.0, 1.0);
        let v = dark * same_colour;
        if v.is_finite() {
            v
        } else {
            0.0
        }
    });
    median(&soft, 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A textured grey floor lit from one side, with a rectangular cast shadow (ambient only
    /// inside) and a dark blue object that is not a shadow.
    fn floor_with_shadow() -> (Raster<[f32; 3]>, Raster<bool>, Raster<bool>) {
        let (w, h) = (96, 72);
        let shadow = Raster::from_fn(w, h, |x, y| (20..45).contains(&x) && (25..50).contains(&y));
        let object = Raster::from_fn(w, h, |x, y| (62..80).contains(&x) && (10..30).contains(&y));
        let photo = Raster::from_fn(w, h, |x, y| {
            let texture = 0.9 + 0.1 * (((x * 7 + y * 13) % 5) as f32 / 4.0);
            if *object.get(x, y) {
                return [0.02, 0.04, 0.2];
            }
            let light = if *shadow.get(x, y) { 0.15 } else { 0.7 };
            [
                0.8 * light * texture,
                0.7 * light * texture,
                0.6 * light * texture,
            ]
        });
        (photo, shadow, object)
    }

    fn iou(mask: &Raster<f32>, truth: &Raster<bool>) -> f32 {
        let (mut i, mut u) = (0, 0);
        for (m, t) in mask.pixels().iter().zip(truth.pixels()) {
            let m = *m > 0.5;
            i += (m && *t) as usize;
            u += (m || *t) as usize;
        }
        i as f32 / u.max(1) as f32
    }

    #[test]
    fn chromaticity_finds_the_shadow_but_not_the_dark_object() {
        let (photo, shadow, object) = floor_with_shadow();
        let mask = shadow_mask(&photo, None, &ShadowOptions::default()).unwrap();
        assert!(iou(&mask, &shadow) > 0.8, "iou {}", iou(&mask, &shadow));
        let on_object = object
            .pixels()
            .iter()
            .zip(mask.pixels())
            .filter(|(o, m)| **o && **m > 0.5)
            .count();
        assert!(on_object < 10, "{on_object} object pixels marked");
        assert!(mask.pixels().iter().all(|v| (0.0..=1.0).contains(v)));
    }

    #[test]
    fn regions_away_from_the_image_corner_find_their_shadow() {
        // A textured floor framed by a brighter wall, with a cast shadow in the floor's far
        // corner. Each region is filtered on its own bounding box grown by the window radius (9
        // px here), which for the floor starts at (7, 5), not at the image's corner; the shadow
        // is found where it is, right up to the floor's edge, and nothing on the wall.
        let (w, h) = (96, 72);
        let frame = |x: usize, y: usize| x < 16 || y < 14 || x >= w - 16 || y >= h - 14;
        let shadow = Raster::from_fn(w, h, |x, y| {
            !frame(x, y) && (56..w - 16).contains(&x) && (40..h - 14).contains(&y)
        });
        let photo = Raster::from_fn(w, h, |x, y| {
            let texture = 0.9 + 0.1 * (((x * 7 + y * 13) % 5) as f32 / 4.0);
            let light = if frame(x, y) {
                2.0
            } else if *shadow.get(x, y) {
                0.15
            } else {
                0.7
            };
            [
                0.4 * light * texture,
                0.35 * light * texture,
                0.3 * light * texture,
            ]
        });
        let regions = Raster::from_fn(w, h, |x, y| frame(x, y) as u32);
        let mask = shadow_mask(&photo, Some(&regions), &ShadowOptions::default()).unwrap();
        assert!(iou(&mask, &shadow) > 0.8, "iou {}", iou(&mask, &shadow));
        for y in 0..h {
            for x in 0..w {
                if frame(x, y) {
                    assert!(*mask.get(x, y) < 0.5, "({x}, {y}): {}", mask.get(x, y));
                }
            }
        }
    }

    #[test]
    fn thesis_method_finds_the_shadow() {
        let (photo, shadow, _) = floor_with_shadow();
        let options = ShadowOptions {
            method: ShadowMethod::Thesis,
            ..Default::default()
        };
        let mask = shadow_mask(&photo, None, &options).unwrap();
        assert!(iou(&mask, &shadow) > 0.5, "iou {}", iou(&mask, &shadow));
    }

    #[test]
    fn regions_keep_a_dark_surface_from_reading_as_shadow() {
        // Two surfaces side by side: a bright one and a uniformly darker grey one (same colour).
        // Without regions the dark one's edge reads as shadow; with them, nothing does.
        let (w, h) = (80, 40);
        let photo = Raster::from_fn(w, h, |x, _| if x < 40 { [0.8; 3] } else { [0.2; 3] });
        let depth = Raster::from_fn(w, h, |x, _| if x < 40 { 2.0 } else { 3.0 });
        let regions = continuity_regions(&depth, None, 0.03, 30.0, 10).unwrap();
        let with = shadow_mask(&photo, Some(&regions), &ShadowOptions::default()).unwrap();
        assert!(with.pixels().iter().all(|v| *v < 0.5));
        let without = shadow_mask(&photo, None, &ShadowOptions::default()).unwrap();
        assert!(without.pixels().iter().any(|v| *v > 0.5));
    }

    #[test]
    fn extreme_photos_give_finite_masks() {
        for photo in [
            Raster::filled(1, 1, [0.0f32; 3]),
            Raster::filled(3, 2, [1.0f32; 3]),
            Raster::filled(40, 30, [0.0f32; 3]),
            Raster::from_fn(20, 20, |x, y| match (x + y) % 4 {
                0 => [f32::NAN; 3],
                1 => [f32::INFINITY; 3],
                2 => [-1.0; 3],
                _ => [1e6; 3],
            }),
        ] {
            for method in [ShadowMethod::Thesis, ShadowMethod::Chromaticity] {
                let options = ShadowOptions {
                    method,
                    ..Default::default()
                };
                let mask = shadow_mask(&photo, None, &options).unwrap();
                assert!(mask
                    .pixels()
                    .iter()
                    .all(|v| v.is_finite() && (0.0..=1.0).contains(v)));
            }
        }
        // A uniform black or white image has no shadow.
        let m = shadow_mask(
            &Raster::filled(40, 30, [0.0f32; 3]),
            None,
            &Default::default(),
        )
        .unwrap();
        assert!(m.pixels().iter().all(|v| *v == 0.0));
    }

    #[test]
    fn bad_input_is_named() {
        let e = shadow_mask(
            &Raster::filled(0, 0, [0.0f32; 3]),
            None,
            &Default::default(),
        )
        .unwrap_err();
        assert!(e.to_string().contains("photo"));
        let e = shadow_mask(
            &Raster::filled(4, 4, [0.0f32; 3]),
            Some(&Raster::filled(3, 4, 0u32)),
            &Default::default(),
        )
        .unwrap_err();
        assert!(e.to_string().contains("region"));
        let bad = ShadowOptions {
            window: 4,
            ..Default::default()
        };
        assert!(shadow_mask(&Raster::filled(4, 4, [0.0f32; 3]), None, &bad)
            .unwrap_err()
            .to_string()
            .contains("window"));
    }
}
