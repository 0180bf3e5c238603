//! Small image filters the estimators share: luminance, box blur (summed-area table), median,
//! connected components. Non-finite input values are treated as 0 by every filter.

use crate::image::{rec709_luma, Raster};

/// Rec. 709 luminance of linear RGB; non-finite or negative channels count as 0.
pub fn luminance(c: [f32; 3]) -> f32 {
    rec709_luma(c.map(|v| if v.is_finite() { v.max(0.0) } else { 0.0 }))
}

/// Mean over the `(2r+1)²` window clipped to the image, optionally counting only pixels where
/// `weight` is non-zero (weighted mean). Pixels whose window holds no weight get `fallback`.
pub(crate) fn box_mean(
    values: &Raster<f32>,
    weight: Option<&Raster<f32>>,
    radius: usize,
    fallback: f32,
) -> Raster<f32> {
    let (w, h) = (values.width(), values.height());
    // Summed-area tables in f64: sums of up to 2^26 values stay exact enough.
    let mut sv = vec![0.0f64; (w + 1) * (h + 1)];
    let mut sw = vec![0.0f64; (w + 1) * (h + 1)];
    for y in 0..h {
        let (mut rv, mut rw) = (0.0f64, 0.0f64);
        for x in 0..w {
            let wt = weight.map_or(1.0, |m| {
                let v = *m.get(x, y);
                if v.is_finite() {
                    v.max(0.0)
                } else {
                    0.0
                }
            }) as f64;
            let v = *values.get(x, y);
            let v = if v.is_finite() { v as f64 } else { 0.0 };
            rv += v * wt;
            rw += wt;
            sv[(y + 1) * (w + 1) + x + 1] = sv[y * (w + 1) + x + 1] + rv;
            sw[(y + 1) * (w + 1) + x + 1] = sw[y * (w + 1) + x + 1] + rw;
        }
    }
    Raster::from_fn(w, h, |x, y| {
        let (x0, y0) = (x.saturating_sub(radius), y.saturating_sub(radius));
        let (x1, y1) = ((x + radius + 1).min(w), (y + radius + 1).min(h));
        let at = |t: &[f64], xx: usize, yy: usize| t[yy * (w + 1) + xx];
        let rect = |t: &[f64]| at(t, x1, y1) - at(t, x0, y1) - at(t, x1, y0) + at(t, x0, y0);
        let total = rect(&sw);
        if total > 1e-9 {
            (rect(&sv) / total) as f32
        } else {
            fallback
        }
    })
}

/// Median over the `(2r+1)²` window clipped to the image.
pub(crate) fn median(values: &Raster<f32>, radius: usize) -> Raster<f32> {
    let (w, h) = (values.width(), values.height());
    let mut window = Vec::with_capacity((2 * radius + 1).pow(2));
    Raster::from_fn(w, h, |x, y| {
        window.clear();
        for yy in y.saturating_sub(radius)..(y + radius + 1).min(h) {
            for xx in x.saturating_sub(radius)..(x + radius + 1).min(w) {
                let v = *values.get(xx, yy);
                window.push(if v.is_finite() { v } else { 0.0 });
            }
        }
        let mid = window.len() / 2;
        *window.select_nth_unstable_by(mid, f32::total_cmp).1
    })
}

/// 8-connected components of the pixels where `inside` is true: a label per pixel (`u32::MAX`
/// outside) and each component's pixel list.
pub(crate) fn components(
    width: usize,
    height: usize,
    inside: impl Fn(usize, usize) -> bool,
) -> (Vec<u32>, Vec<Vec<(usize, usize)>>) {
    let mut label = vec![u32::MAX; width * height];
    let mut groups: Vec<Vec<(usize, usize)>> = Vec::new();
    let mut stack = Vec::new();
    for y0 in 0..height {
        for x0 in 0..width {
            if label[y0 * width + x0] != u32::MAX || !inside(x0, y0) {
                continue;
            }
            let id = groups.len() as u32;
            let mut group = Vec::new();
            label[y0 * width + x0] = id;
            stack.push((x0, y0));
            while let Some((x, y)) = stack.pop() {
                group.push((x, y));
                for dy in -1i64..=1 {
                    for dx in -1i64..=1 {
                        let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                        if nx < 0 || ny < 0 || nx >= width as i64 || ny >= height as i64 {
                            continue;
                        }
                        let (nx, ny) = (nx as usize, ny as usize);
                        if label[ny * width + nx] == u32::MAX && inside(nx, ny) {
                            label[ny * width + nx] = id;
                            stack.push((nx, ny));
                        }
                    }
                }
            }
            groups.push(group);
        }
    }
    (label, groups)
}

/// Checks that an image is non-empty and returns its size.
pub(crate) fn check_size<T>(what: &str, r: &Raster<T>) -> crate::error::Result<(usize, usize)> {
    if r.width() == 0 || r.height() == 0 {
        return Err(crate::error::Error::invalid(format!(
            "{what} is empty ({}x{})",
            r.width(),
            r.height()
        )));
    }
    Ok((r.width(), r.height()))
}

/// Checks that the photo is not empty and has the camera's image size; returns its size.
pub(crate) fn check_photo_camera<T>(
    photo: &Raster<T>,
    camera: &crate::camera::Camera,
) -> crate::error::Result<(usize, usize)> {
    let (w, h) = check_size("photo", photo)?;
    if (w, h) != (camera.width as usize, camera.height as usize) {
        return Err(crate::error::Error::SizeMismatch(format!(
            "photo is {w}x{h} but the camera's image is {}x{}",
            camera.width, camera.height
        )));
    }
    Ok((w, h))
}

/// Checks that `other` has the size of the photo.
pub(crate) fn check_same<T, U>(
    what: &str,
    photo: &Raster<T>,
    other: &Raster<U>,
) -> crate::error::Result<()> {
    if (photo.width(), photo.height()) != (other.width(), other.height()) {
        return Err(crate::error::Error::SizeMismatch(format!(
            "{what} is {}x{} but the photo is {}x{}",
            other.width(),
            other.height(),
            photo.width(),
            photo.height()
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_mean_of_constant_is_constant_and_weights_select() {
        let r = Raster::filled(7, 5, 2.0f32);
        let m = box_mean(&r, None, 2, 0.0);
        assert!(m.pixels().iter().all(|v| (v - 2.0).abs() < 1e-6));
        let values = Raster::from_fn(6, 1, |x, _| x as f32);
        let weight = Raster::from_fn(6, 1, |x, _| if x % 2 == 0 { 1.0 } else { 0.0 });
        let m = box_mean(&values, Some(&weight), 1, -1.0);
        // Pixel 1's window holds 0, 1, 2 with weights 1, 0, 1.
        assert!((m.get(1, 0) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn median_removes_a_lone_outlier_and_components_split() {
        let mut r = Raster::filled(5, 5, 1.0f32);
        *r.get_mut(2, 2) = 100.0;
        assert_eq!(*median(&r, 1).get(2, 2), 1.0);
        let (label, groups) = components(5, 1, |x, _| x != 2);
        assert_eq!(groups.len(), 2);
        assert_eq!(label[2], u32::MAX);
    }
}
