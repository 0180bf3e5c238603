//! Checks of a composite written by a host example (C, C++, built by hand or by CMake /
//! pkg-config): a binary PPM of the composite and a PGM of the artefact's coverage, compared
//! with the photo (the left view) of the synthetic scene.

#![allow(dead_code)]

use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// An 8-bit binary PNM image (`P6` RGB or `P5` grey).
pub struct Pnm {
    pub width: usize,
    pub height: usize,
    pub channels: usize,
    pub pixels: Vec<u8>,
}

impl Pnm {
    pub fn read(path: &Path) -> Pnm {
        let bytes =
            std::fs::read(path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
        // Header: magic, width, height, maxval, separated by whitespace, then one whitespace byte.
        let mut fields = Vec::new();
        let mut i = 0;
        while fields.len() < 4 {
            while bytes[i].is_ascii_whitespace() {
                i += 1;
            }
            let start = i;
            while !bytes[i].is_ascii_whitespace() {
                i += 1;
            }
            fields.push(String::from_utf8_lossy(&bytes[start..i]).to_string());
        }
        i += 1;
        let channels = match fields[0].as_str() {
            "P6" => 3,
            "P5" => 1,
            other => panic!("{}: not a binary PNM ({other})", path.display()),
        };
        let width: usize = fields[1].parse().unwrap();
        let height: usize = fields[2].parse().unwrap();
        assert_eq!(fields[3], "255", "{}: maxval", path.display());
        let pixels = bytes[i..].to_vec();
        assert_eq!(
            pixels.len(),
            width * height * channels,
            "{}: pixel data size",
            path.display()
        );
        Pnm {
            width,
            height,
            channels,
            pixels,
        }
    }

    pub fn at(&self, x: usize, y: usize) -> &[u8] {
        let i = (y * self.width + x) * self.channels;
        &self.pixels[i..i + self.channels]
    }
}

/// The mask file next to a composite `OUT.ppm`: `OUT-mask.pgm`.
pub fn mask_path(composite: &Path) -> PathBuf {
    let stem = composite.file_stem().unwrap().to_string_lossy();
    composite.with_file_name(format!("{stem}-mask.pgm"))
}

/// The composite at `composite` (and its mask) of the synthetic scene's photo `left` with an
/// artefact placed at pixel (`px`, `py`): the artefact covers that pixel and changes the photo
/// there, and the photo is unchanged far from it. `printed` is the example's key=value output.
pub fn check_composite(
    left: &Path,
    composite: &Path,
    px: f32,
    py: f32,
    printed: &HashMap<String, String>,
) {
    let photo = parallax::image::Image::load(left, &Default::default()).expect("load photo");
    let (w, h) = (photo.width() as usize, photo.height() as usize);
    let bpp = photo.format().bytes_per_pixel();
    let photo_bytes = photo.as_bytes();
    let photo_at = |x: usize, y: usize| -> [u8; 3] {
        let i = (y * w + x) * bpp;
        [photo_bytes[i], photo_bytes[i + 1], photo_bytes[i + 2]]
    };
    let c = Pnm::read(composite);
    let m = Pnm::read(&mask_path(composite));
    assert_eq!((c.width, c.height, c.channels), (w, h, 3), "composite size");
    assert_eq!((m.width, m.height, m.channels), (w, h, 1), "mask size");

    // The artefact stands where it was placed. Its base touches the scene's surface at that
    // pixel, so the contact itself can be hidden by the (noisy, stereo) surface it sits on: the
    // silhouette must reach within 2 px of the pixel. The example's printout agrees with the mask.
    let (x0, y0) = (px as usize, py as usize);
    let near_contact = (y0.saturating_sub(2)..(y0 + 3).min(h))
        .flat_map(|y| (x0.saturating_sub(2)..(x0 + 3).min(w)).map(move |x| (x, y)))
        .any(|(x, y)| m.at(x, y)[0] > 127);
    assert!(
        near_contact,
        "no artefact pixel within 2 px of ({x0}, {y0}): the artefact is not where it was placed"
    );
    if let Some(v) = printed.get("mask_at_pixel") {
        assert_eq!(v.parse::<u8>().unwrap(), m.at(x0, y0)[0], "printed mask");
    }
    let covered: Vec<(usize, usize)> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .filter(|&(x, y)| m.at(x, y)[0] > 127)
        .collect();
    if let Some(v) = printed.get("mask_pixels") {
        assert_eq!(
            v.parse::<usize>().unwrap(),
            covered.len(),
            "printed mask count"
        );
    }
    // A 0.3 m box a couple of metres away covers some tens to some thousands of pixels.
    assert!(
        covered.len() >= 20 && covered.len() < w * h / 4,
        "{} covered pixels",
        covered.len()
    );

    // Where the artefact is, the composite is not the photo.
    let diff = |x: usize, y: usize| -> u32 {
        let p = photo_at(x, y);
        let q = c.at(x, y);
        (0..3)
            .map(|i| (p[i] as i32 - q[i] as i32).unsigned_abs())
            .sum()
    };
    let mean_inside =
        covered.iter().map(|&(x, y)| diff(x, y) as f64).sum::<f64>() / covered.len() as f64;
    assert!(
        mean_inside > 6.0,
        "the artefact's pixels differ from the photo by only {mean_inside:.2} (sum of RGB levels)"
    );

    // Far from it (no covered pixel within 40 px, the top third: walls and table) the composite
    // is the photo up to rounding and the faint soft shadow and blocked ambient light of the box
    // (a few levels at most there).
    let far = |x: usize, y: usize| {
        covered.iter().all(|&(cx, cy)| {
            let (dx, dy) = (cx as f64 - x as f64, cy as f64 - y as f64);
            dx * dx + dy * dy > 40.0 * 40.0
        })
    };
    let (mut far_pixels, mut worst, mut total) = (0usize, 0u32, 0u64);
    for y in 0..h / 3 {
        for x in 0..w {
            if far(x, y) {
                far_pixels += 1;
                worst = worst.max(diff(x, y));
                total += diff(x, y) as u64;
            }
        }
    }
    assert!(far_pixels > w * h / 10, "only {far_pixels} pixels far away");
    let mean_far = total as f64 / far_pixels as f64;
    assert!(
        worst <= 12 && mean_far < 2.0,
        "far from the artefact the composite differs from the photo by up to {worst} levels \
         (mean {mean_far:.2})"
    );
}
