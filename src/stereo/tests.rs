//! Tests of the whole matcher on synthetic pairs with exact disparity, and on bad and extreme input.

use super::*;
use crate::image::{Image, PixelFormat};

/// A smooth, richly textured grey function of continuous coordinates, so that a view shifted by a
/// fractional disparity can be rendered exactly.
pub(crate) fn texture(x: f32, y: f32) -> u8 {
    let hash = |i: i32, j: i32| {
        let mut v = (i as u32).wrapping_mul(0x9E37_79B1) ^ (j as u32).wrapping_mul(0x85EB_CA77);
        v ^= v >> 15;
        v = v.wrapping_mul(0x2C1B_3C6D);
        v ^= v >> 12;
        (v & 0xffff) as f32 / 65535.0
    };
    let noise = |x: f32, y: f32| {
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let s = |t: f32| t * t * (3.0 - 2.0 * t);
        let (sx, sy) = (s(fx), s(fy));
        let (i, j) = (x0 as i32, y0 as i32);
        let top = hash(i, j) * (1.0 - sx) + hash(i + 1, j) * sx;
        let bottom = hash(i, j + 1) * (1.0 - sx) + hash(i + 1, j + 1) * sx;
        top * (1.0 - sy) + bottom * sy
    };
    let v = 128.0
        + 70.0 * (noise(x / 2.3, y / 2.3) - 0.5) * 2.0
        + 30.0 * (0.31 * x + 0.17 * y).sin()
        + 20.0 * (noise(x / 7.0 + 50.0, y / 7.0) - 0.5);
    v.clamp(0.0, 255.0) as u8
}

fn gray(w: usize, h: usize, f: impl Fn(usize, usize) -> u8) -> Image {
    let data = (0..w * h).map(|p| f(p % w, p / w)).collect();
    Image::from_bytes(w as u32, h as u32, PixelFormat::Gray8, data).unwrap()
}

fn opts(max: u32) -> StereoOptions {
    StereoOptions {
        max_disparity: max,
        ..StereoOptions::default()
    }
}

fn run(l: &Image, r: &Image, o: &StereoOptions) -> Disparity {
    let d = match_pair(&l.view(), &r.view(), o).unwrap();
    assert!(
        d.disparity.pixels().iter().all(|v| v.is_finite()),
        "non-finite disparity"
    );
    assert!(
        d.confidence
            .pixels()
            .iter()
            .all(|v| (0.0..=1.0).contains(v)),
        "confidence out of [0, 1]"
    );
    d
}

/// Mean absolute error against `truth` over pixels with `x ≥ margin` (left of it has no match).
fn mean_error(d: &Raster<f32>, margin: usize, truth: impl Fn(usize, usize) -> f32) -> f32 {
    let (w, h) = (d.width(), d.height());
    let mut sum = 0.0;
    let mut n = 0;
    for y in 3..h - 3 {
        for x in margin..w - 3 {
            sum += (d.get(x, y) - truth(x, y)).abs();
            n += 1;
        }
    }
    sum / n as f32
}

#[test]
fn bad_input_gets_clear_errors() {
    let a = gray(32, 16, |x, y| texture(x as f32, y as f32));
    let b = gray(30, 16, |x, y| texture(x as f32, y as f32));
    let e = match_pair(&a.view(), &b.view(), &opts(8)).unwrap_err();
    assert!(
        matches!(e, Error::SizeMismatch(_)) && e.to_string().contains("32x16"),
        "{e}"
    );
    let thin = gray(1, 16, |_, _| 5);
    let e = match_pair(&thin.view(), &thin.view(), &opts(1)).unwrap_err();
    assert!(e.to_string().contains("1x16"), "{e}");
    let row = gray(16, 1, |x, _| x as u8);
    assert!(match_pair(&row.view(), &row.view(), &opts(1)).is_err());
    assert!(Image::from_bytes(0, 5, PixelFormat::Gray8, vec![]).is_err());
    let e = match_pair(&a.view(), &a.view(), &opts(0)).unwrap_err();
    assert!(e.to_string().contains("max_disparity"), "{e}");
    let e = match_pair(&a.view(), &a.view(), &opts(32)).unwrap_err();
    assert!(e.to_string().contains("width"), "{e}");
    let bad_calib = StereoCalibration {
        baseline_m: -1.0,
        ..assumed_calibration(32, 16).unwrap()
    };
    assert!(depth_map(&Raster::filled(2, 2, 1.0), &bad_calib).is_err());
    let nan_calib = StereoCalibration {
        focal_px: f64::NAN,
        ..assumed_calibration(32, 16).unwrap()
    };
    assert!(depth_map(&Raster::filled(2, 2, 1.0), &nan_calib).is_err());
}

#[test]
fn extreme_but_legal_pairs_give_finite_output() {
    let (w, h) = (64, 40);
    let flat = gray(w, h, |_, _| 90);
    let white = gray(w, h, |_, _| 255);
    let noise_l = gray(w, h, |x, y| ((x * 7919 + y * 6151) % 251) as u8);
    let noise_r = gray(w, h, |x, y| ((x * 4241 + y * 1543 + 17) % 253) as u8);
    let other = gray(w, h, |x, y| texture(x as f32 + 500.0, y as f32 + 300.0));
    let tex = gray(w, h, |x, y| texture(x as f32, y as f32));
    for preset in Preset::ALL {
        let o = StereoOptions {
            max_disparity: 16,
            ..StereoOptions::preset(preset)
        };
        // Flat and identical: every disparity costs the same, and aggregation carries in
        // disparity 0 from the left border; nothing was measured, so the confidence is 0.
        for img in [&flat, &white] {
            let d = run(img, img, &o);
            assert!(d.disparity.pixels().iter().all(|&v| v == 0.0), "{preset}");
            assert!(d.confidence.pixels().iter().all(|&c| c == 0.0), "{preset}");
            assert_eq!(d.stats.textureless_fraction, 1.0, "{preset}");
        }
        run(&noise_l, &noise_r, &o);
        // No overlap: the right view shows something else entirely.
        run(&tex, &other, &o);
    }
    for o in [
        StereoOptions::thesis(),
        StereoOptions {
            fill: false,
            ..opts(16)
        },
    ] {
        let o = StereoOptions {
            max_disparity: 16,
            ..o
        };
        let d = match_pair(&noise_l.view(), &noise_r.view(), &o).unwrap();
        assert!(d
            .disparity
            .pixels()
            .iter()
            .all(|v| v.is_nan() || (0.0..=16.0).contains(v)));
    }
    // No fill keeps holes as NaN, with confidence 0 there.
    let d = match_pair(
        &noise_l.view(),
        &noise_r.view(),
        &StereoOptions {
            fill: false,
            ..opts(16)
        },
    )
    .unwrap();
    assert!(d.disparity.pixels().iter().any(|v| v.is_nan()));
    for (v, c) in d.disparity.pixels().iter().zip(d.confidence.pixels()) {
        assert!(!v.is_nan() || *c == 0.0);
    }
}

#[test]
fn a_stretch_with_nothing_to_match_gets_confidence_zero() {
    // A textured pair at disparity 5 with a uniform band wider than the search across the
    // middle of both views.
    let (w, h) = (160, 40);
    let band = |x: f32| (60.0..100.0).contains(&x);
    let view = |shift: f32| {
        gray(w, h, move |x, y| {
            let x = x as f32 + shift;
            if band(x) {
                100
            } else {
                texture(x, y as f32)
            }
        })
    };
    let (l, r) = (view(0.0), view(5.0));
    for preset in Preset::ALL {
        let o = StereoOptions {
            max_disparity: 16,
            ..StereoOptions::preset(preset)
        };
        let d = run(&l, &r, &o);
        let confident = |xs: std::ops::Range<usize>| {
            let n = xs.len() * h;
            let c = xs
                .flat_map(|x| (0..h).map(move |y| (x, y)))
                .filter(|&(x, y)| *d.confidence.get(x, y) > 0.0)
                .count();
            c as f32 / n as f32
        };
        // The band's inside, beyond the census window and the search from its edges: nothing.
        assert_eq!(confident(75..88), 0.0, "{preset}");
        // The texture beside it was measured.
        assert!(
            confident(110..150) > 0.9,
            "{preset}: {}",
            confident(110..150)
        );
        let share = d.stats.textureless_fraction;
        assert!((0.05..0.3).contains(&share), "{preset}: {share}");
    }
    // A textured pair has something to match nearly everywhere, identical views included.
    let d = run(&l, &l, &opts(16));
    assert!(d.confidence.get(130, 20) > &0.0);
    let tex = gray(w, h, |x, y| texture(x as f32, y as f32));
    let shifted = gray(w, h, |x, y| texture(x as f32 + 5.0, y as f32));
    for (a, b) in [(&tex, &tex), (&tex, &shifted)] {
        let share = run(a, b, &opts(16)).stats.textureless_fraction;
        assert!(share < 0.02, "{share}");
    }
}

#[test]
fn identical_images_give_zero_everywhere() {
    let img = gray(80, 50, |x, y| texture(x as f32, y as f32));
    for o in [
        opts(20),
        StereoOptions::preset(Preset::Fast),
        StereoOptions::thesis(),
    ] {
        let o = StereoOptions {
            max_disparity: 20,
            ..o
        };
        let d = run(&img, &img, &o);
        assert!(
            d.disparity.pixels().iter().all(|&v| v == 0.0),
            "{:?}",
            o.aggregation
        );
    }
}

#[test]
fn tiny_ranges_and_narrow_images_work() {
    // Max disparity 1 on a shift of 1.
    let l = gray(48, 24, |x, y| texture(x as f32, y as f32));
    let r = gray(48, 24, |x, y| texture(x as f32 + 1.0, y as f32));
    let d = run(&l, &r, &opts(1));
    assert!(mean_error(&d.disparity, 4, |_, _| 1.0) < 0.1);
    // 16 pixels wide.
    let l = gray(16, 30, |x, y| texture(x as f32, y as f32));
    let r = gray(16, 30, |x, y| texture(x as f32 + 3.0, y as f32));
    for preset in Preset::ALL {
        let o = StereoOptions {
            max_disparity: 8,
            ..StereoOptions::preset(preset)
        };
        run(&l, &r, &o);
    }
    let d = run(&l, &r, &opts(8));
    assert!(mean_error(&d.disparity, 6, |_, _| 3.0) < 0.5);
    // Narrower than the smoothing's widest tap spacing (4 px with 3 passes), and a 2-px image.
    for (w, h) in [(3, 20), (2, 2), (5, 3)] {
        let l = gray(w, h, |x, y| texture(x as f32, y as f32));
        let r = gray(w, h, |x, y| texture(x as f32 + 1.0, y as f32));
        for preset in Preset::ALL {
            let o = StereoOptions {
                max_disparity: 1,
                ..StereoOptions::preset(preset)
            };
            run(&l, &r, &o);
        }
    }
}

#[test]
fn huge_penalties_do_not_overflow() {
    let l = gray(64, 40, |x, y| texture(x as f32, y as f32));
    let r = gray(64, 40, |x, y| texture(x as f32 + 5.0, y as f32));
    let o = StereoOptions {
        p1: 60_000,
        p2: u16::MAX,
        ..opts(16)
    };
    let d = run(&l, &r, &o);
    assert!(mean_error(&d.disparity, 20, |_, _| 5.0) < 0.2);
}

#[test]
fn fronto_parallel_plane_has_sub_pixel_accuracy() {
    let (w, h) = (120, 60);
    for truth in [7.0f32, 7.25, 7.5, 9.8] {
        let l = gray(w, h, |x, y| texture(x as f32, y as f32));
        let r = gray(w, h, |x, y| texture(x as f32 + truth, y as f32));
        // Without the local fit (`balanced`), sub-pixel positions come from the census costs
        // alone, which lean towards whole pixels by about a tenth of a pixel.
        for (o, limit) in [
            (opts(24), 0.15),
            (
                StereoOptions {
                    max_disparity: 24,
                    ..StereoOptions::preset(Preset::Quality)
                },
                0.1,
            ),
        ] {
            let d = run(&l, &r, &o);
            let e = mean_error(&d.disparity, 30, |_, _| truth);
            assert!(e < limit, "disparity {truth}: mean error {e}");
        }
    }
}

/// Background plane at disparity 4 on the left, foreground at 12 from column 60 on.
fn step_pair(w: usize, h: usize) -> (Image, Image, impl Fn(usize, usize) -> f32) {
    let edge = 60.0;
    let (bg, fg) = (4.0, 12.0);
    let back = |x: f32, y: f32| texture(x, y);
    let front = |x: f32, y: f32| texture(x + 1000.0, y + 77.0);
    let l = gray(w, h, |x, y| {
        if (x as f32) < edge {
            back(x as f32, y as f32)
        } else {
            front(x as f32, y as f32)
        }
    });
    let r = gray(w, h, |x, y| {
        let (xb, xf) = (x as f32 + bg, x as f32 + fg);
        if xf >= edge {
            front(xf, y as f32)
        } else {
            back(xb, y as f32)
        }
    });
    (
        l,
        r,
        move |x: usize, _| if (x as f32) < edge { bg } else { fg },
    )
}

/// Pixels with an error of at least `tol` px, as (x, y), outside `skip` px of the step at x = 60.
fn step_errors(
    d: &Disparity,
    truth: &impl Fn(usize, usize) -> f32,
    w: usize,
    h: usize,
    tol: f32,
) -> Vec<(usize, usize)> {
    let mut bad = Vec::new();
    for y in 4..h - 4 {
        for x in 20..w - 4 {
            if (d.disparity.get(x, y) - truth(x, y)).abs() >= tol {
                bad.push((x, y));
            }
        }
    }
    bad
}

#[test]
fn a_step_edge_stays_sharp() {
    let (w, h) = (140, 50);
    let (l, r, truth) = step_pair(w, h);
    let evaluated = ((h - 8) * (w - 24)) as f32;
    for preset in Preset::ALL {
        let o = StereoOptions {
            max_disparity: 24,
            ..StereoOptions::preset(preset)
        };
        let d = run(&l, &r, &o);
        let bad = step_errors(&d, &truth, w, h, 0.5);
        let beyond = |px: usize| bad.iter().filter(|(x, _)| x.abs_diff(60) > px).count();
        // Occluded background (x in 52..60) must be filled as background, the edge must not
        // spread: within 2 px of it everywhere but in a few rows, and always within 10 px.
        assert_eq!(beyond(10), 0, "{preset}: {bad:?}");
        let share = beyond(2) as f32 / evaluated;
        // 4 paths and no local fit (`fast`, `balanced`) let the edge wander a little more.
        let limit = match preset {
            Preset::Fast => 0.05,
            Preset::Balanced => 0.01,
            Preset::Quality => 0.005,
        };
        assert!(
            share <= limit,
            "{preset}: {:.2} % wrong beyond 2 px: {bad:?}",
            share * 100.0
        );
    }
}

#[test]
fn slanted_plane_is_followed() {
    let (w, h) = (160, 80);
    // d(x, y) = a + b·x + c·y in left coordinates; right pixel x_r shows left x_l = (x_r + a + c·y)/(1 − b).
    let (a, b, c) = (6.0f32, 0.05f32, 0.04f32);
    let truth = move |x: usize, y: usize| a + b * x as f32 + c * y as f32;
    let l = gray(w, h, |x, y| texture(x as f32, y as f32));
    let r = gray(w, h, |x, y| {
        texture((x as f32 + a + c * y as f32) / (1.0 - b), y as f32)
    });
    for o in [
        opts(24),
        StereoOptions {
            max_disparity: 24,
            ..StereoOptions::preset(Preset::Fast)
        },
    ] {
        let d = run(&l, &r, &o);
        let e = mean_error(&d.disparity, 24, truth);
        assert!(e < 0.25, "mean error {e}");
    }
}

#[test]
fn thesis_method_finds_the_plane() {
    let l = gray(100, 40, |x, y| texture(x as f32, y as f32));
    let r = gray(100, 40, |x, y| texture(x as f32 + 6.0, y as f32));
    let o = StereoOptions {
        max_disparity: 16,
        ..StereoOptions::thesis()
    };
    let d = run(&l, &r, &o);
    assert!(mean_error(&d.disparity, 24, |_, _| 6.0) < 0.25);
    assert!(d.stats.timings.iter().any(|(n, _)| n == "stereo.aggregate"));
}

#[test]
fn coarse_to_fine_matches_the_full_search() {
    let (w, h) = (160, 64);
    let (l, r, truth) = step_pair(w, h);
    // The same matcher with and without the narrowed search (`quality`'s, whose edges
    // `a_step_edge_stays_sharp` holds to the tightest limit).
    let base = StereoOptions {
        max_disparity: 40,
        ..StereoOptions::preset(Preset::Quality)
    };
    let full = run(
        &l,
        &r,
        &StereoOptions {
            coarse_levels: 0,
            ..base.clone()
        },
    );
    let o = StereoOptions {
        coarse_levels: 1,
        coarse_window: 12,
        ..base
    };
    let c2f = run(&l, &r, &o);
    assert!(c2f.stats.timings.iter().any(|(n, _)| n == "stereo.coarse"));
    // Away from the depth step both are right to a pixel; at the step the narrowed search may
    // spread the edge by a few pixels.
    for d in [&full, &c2f] {
        let bad = step_errors(d, &truth, w, h, 1.0);
        assert!(bad.iter().all(|(x, _)| x.abs_diff(60) <= 6), "{bad:?}");
    }
}

#[test]
fn misaligned_pair_is_corrected_before_matching() {
    let (w, h) = (200, 120);
    let l = gray(w, h, |x, y| texture(x as f32, y as f32));
    let r = gray(w, h, |x, y| texture(x as f32 + 5.0, y as f32 - 4.0));
    let plain = run(&l, &r, &opts(16));
    let o = StereoOptions {
        correct_misalignment: true,
        ..opts(16)
    };
    let fixed = run(&l, &r, &o);
    let (dy, _) = fixed.stats.misalignment.unwrap();
    assert!((dy - 4.0).abs() <= 0.5, "dy {dy}");
    let e_fixed = mean_error(&fixed.disparity, 30, |_, _| 5.0);
    assert!(e_fixed < 0.3, "{e_fixed}");
    assert!(e_fixed < mean_error(&plain.disparity, 30, |_, _| 5.0));
}

#[test]
fn depth_follows_the_calibration() {
    let calib = StereoCalibration::from_focal_baseline(1000.0, 0.1, 8, 8).unwrap();
    let d = Raster::from_vec(3, 1, vec![50.0, f32::NAN, 0.0]);
    let z = depth_map(&d, &calib).unwrap();
    assert!((z.get(0, 0) - 2.0).abs() < 1e-6);
    assert!(z.get(1, 0).is_nan() && z.get(2, 0).is_nan());
    // Without calibration: f = w / (2 tan 30°), baseline 1.
    let assumed = assumed_calibration(640, 480).unwrap();
    assert!((assumed.focal_px - 320.0 / (30f64).to_radians().tan()).abs() < 1e-9);
}

#[test]
fn stats_name_the_sub_stages_and_memory() {
    let l = gray(96, 48, |x, y| texture(x as f32, y as f32));
    let r = gray(96, 48, |x, y| texture(x as f32 + 3.0, y as f32));
    let d = run(&l, &r, &opts(16));
    let names: Vec<&str> = d.stats.timings.iter().map(|(n, _)| n.as_str()).collect();
    for n in [
        "stereo.cost",
        "stereo.aggregate",
        "stereo.decide",
        "stereo.fill",
    ] {
        assert!(names.contains(&n), "{names:?}");
    }
    // At least the aggregated volume, 2 bytes per pixel and disparity.
    assert!(d.stats.peak_working_bytes >= 96 * 48 * 17 * 2);
    assert!((0.0..=1.0).contains(&d.stats.invalid_fraction));
}

#[test]
fn a_residual_vertical_offset_is_measured_and_undone() {
    // A slanted textured plane whose right view sits 0.4 px lower, growing to 0.6 px at the
    // bottom (an imperfect rectification, as in Middlebury's "imperfect" pairs).
    let (w, h) = (240, 160);
    let truth = |x: usize, _y: usize| 8.0 + 4.0 * x as f32 / w as f32;
    let dy = |y: f32| 0.4 + 0.2 * (y - h as f32 / 2.0) / (h as f32 / 2.0);
    let l = gray(w, h, |x, y| texture(x as f32, y as f32));
    let r = gray(w, h, |x, y| {
        // Right pixel xr shows the left point at x with x − d(x) = xr (solved for this plane).
        let x = (x as f32 + 8.0) / (1.0 - 4.0 / w as f32);
        texture(x, y as f32 - dy(y as f32))
    });
    // `quality`'s local fit resolves what the correction restores below a pixel.
    let o = StereoOptions {
        max_disparity: 24,
        ..StereoOptions::preset(Preset::Quality)
    };
    let with = run(&l, &r, &o);
    let without = run(
        &l,
        &r,
        &StereoOptions {
            refine_alignment: false,
            ..o.clone()
        },
    );
    let m = with
        .stats
        .residual_alignment
        .expect("a 0.4 px offset is corrected");
    assert!((m.offset - 0.4).abs() < 0.05, "{m:?}");
    assert!((m.per_row - 0.2 / 80.0).abs() < 0.0008, "{m:?}");
    assert!(without.stats.residual_alignment.is_none());
    let (e_with, e_without) = (
        mean_error(&with.disparity, 30, truth),
        mean_error(&without.disparity, 30, truth),
    );
    assert!(
        e_with < 0.1 && e_with < 0.7 * e_without,
        "{e_with} vs {e_without}"
    );
    assert!(with.stats.timings.iter().any(|(n, _)| n == "stereo.align"));
    // An exactly rectified pair is left alone (no resampling below 0.1 px at any corner).
    let r0 = gray(w, h, |x, y| {
        let x = (x as f32 + 8.0) / (1.0 - 4.0 / w as f32);
        texture(x, y as f32)
    });
    assert!(run(&l, &r0, &opts(24)).stats.residual_alignment.is_none());
}

#[test]
fn grey_levels_of_every_8_bit_layout_match_the_luma_of_the_photo() {
    use crate::mesh::surfaces::XorShift;
    let mut rng = XorShift(0x9e7);
    let (w, h) = (7, 5);
    let rgba: Vec<u8> = (0..w * h * 4).map(|_| rng.next_u64() as u8).collect();
    let rgb: Vec<u8> = rgba
        .chunks_exact(4)
        .flat_map(|p| [p[0], p[1], p[2]])
        .collect();
    let bgra: Vec<u8> = rgba
        .chunks_exact(4)
        .flat_map(|p| [p[2], p[1], p[0], p[3]])
        .collect();
    let grey8: Vec<u8> = rgba.chunks_exact(4).map(|p| p[1]).collect();
    // Rows padded by 3 bytes: the stride is honoured.
    let padded = |data: &[u8], bytes: usize| -> Vec<u8> {
        data.chunks_exact(w * bytes)
            .flat_map(|row| row.iter().copied().chain([0xAA; 3]))
            .collect()
    };
    for (data, format, bytes) in [
        (&rgba, PixelFormat::Rgba8, 4),
        (&rgb, PixelFormat::Rgb8, 3),
        (&bgra, PixelFormat::Bgra8, 4),
        (&grey8, PixelFormat::Gray8, 1),
    ] {
        let bytes_padded = padded(data, bytes);
        let view =
            ImageView::new(&bytes_padded, w as u32, h as u32, w * bytes + 3, format).unwrap();
        let want = view
            .to_luma()
            .map(|&v| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8);
        assert_eq!(grey(&view), want, "{format:?}");
    }
    // The three colour layouts hold the same pixels.
    let view = |data: &[u8], format, bytes: usize| {
        grey(&ImageView::new(data, w as u32, h as u32, w * bytes, format).unwrap())
    };
    let first = view(&rgba, PixelFormat::Rgba8, 4);
    assert_eq!(view(&rgb, PixelFormat::Rgb8, 3), first);
    assert_eq!(view(&bgra, PixelFormat::Bgra8, 4), first);
    // Every red and green code value against each other, blue varying: the looked-up terms
    // give the grey levels of the photo's luma.
    let all: Vec<u8> = (0..256 * 256)
        .flat_map(|i| [(i % 256) as u8, (i / 256) as u8, (i * 7 % 251) as u8])
        .collect();
    let view = ImageView::new(&all, 256, 256, 256 * 3, PixelFormat::Rgb8).unwrap();
    let want = view
        .to_luma()
        .map(|&v| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8);
    assert_eq!(grey(&view), want);
}

#[test]
fn penalties_grow_with_the_noise_of_the_pair_and_stay_for_a_clean_one() {
    use crate::mesh::surfaces::XorShift;
    let (w, h, d) = (120, 60, 6.0);
    // A textured plane at 6 px, and the same views with independent noise of up to ±50 grey
    // levels in each.
    let clean_l = gray(w, h, |x, y| texture(x as f32, y as f32));
    let clean_r = gray(w, h, |x, y| texture(x as f32 + d, y as f32));
    let mut rng = XorShift(0x5eed);
    let mut noisy = |img: &Image| {
        let data: Vec<u8> = img
            .view()
            .row(0)
            .iter()
            .chain((1..h as u32).flat_map(|y| img.view().row(y).iter()))
            .map(|&v| (v as i32 + (rng.next_u64() % 101) as i32 - 50).clamp(0, 255) as u8)
            .collect();
        Image::from_bytes(w as u32, h as u32, PixelFormat::Gray8, data).unwrap()
    };
    let (noisy_l, noisy_r) = (noisy(&clean_l), noisy(&clean_r));
    let o = StereoOptions {
        noise_adaptive_penalties: true,
        ..opts(16)
    };
    let clean = run(&clean_l, &clean_r, &o);
    assert_eq!(clean.stats.penalty_scale, 1.0);
    let floor = clean.stats.match_cost_floor.expect("measured");
    assert!(floor < noise::CLEAN_MATCH_COST, "clean floor {floor}");

    let adapted = run(&noisy_l, &noisy_r, &o);
    let floor = adapted.stats.match_cost_floor.expect("measured");
    assert!(floor > noise::CLEAN_MATCH_COST, "noisy floor {floor}");
    assert!(
        adapted.stats.penalty_scale > 1.2,
        "{}",
        adapted.stats.penalty_scale
    );
    let stages = |d: &Disparity| -> Vec<String> {
        d.stats
            .timings
            .iter()
            .map(|(name, _)| name.clone())
            .collect()
    };
    assert!(stages(&adapted).contains(&"stereo.noise".to_string()));
    let fixed = run(
        &noisy_l,
        &noisy_r,
        &StereoOptions {
            noise_adaptive_penalties: false,
            ..o.clone()
        },
    );
    assert_eq!(fixed.stats.penalty_scale, 1.0);
    assert_eq!(fixed.stats.match_cost_floor, None);
    assert!(!stages(&fixed).contains(&"stereo.noise".to_string()));
    // The stronger smoothness pays off on the noisy pair.
    let (e_adapted, e_fixed) = (
        mean_error(&adapted.disparity, 12, |_, _| d),
        mean_error(&fixed.disparity, 12, |_, _| d),
    );
    assert!(
        e_adapted < e_fixed,
        "adapted {e_adapted} vs fixed {e_fixed}"
    );
}

#[test]
fn a_kept_matcher_gives_the_one_off_results_whatever_it_matched_before() {
    // Each match reuses buffers holding the previous, larger or differently shaped match's
    // values: a read before a write would see them instead of a fresh buffer's zeros.
    let big = step_pair(160, 64);
    let small = step_pair(97, 41);
    let runs = [
        (&big, StereoOptions::preset(Preset::Quality)),
        (&small, StereoOptions::preset(Preset::Balanced)),
        (&small, StereoOptions::preset(Preset::Fast)),
        (
            &big,
            StereoOptions {
                cost: CostKind::Sad,
                aggregation: Aggregation::Sgm4,
                coarse_levels: 0,
                ..StereoOptions::preset(Preset::Balanced)
            },
        ),
        (&big, StereoOptions::preset(Preset::Balanced)),
        (&small, StereoOptions::preset(Preset::Quality)),
    ];
    let bits = |r: &Raster<f32>| r.pixels().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    let mut matcher = StereoMatcher::new();
    assert_eq!(matcher.retained_bytes(), 0);
    for (i, ((l, r, _), o)) in runs.iter().enumerate() {
        let o = StereoOptions {
            max_disparity: 40,
            ..o.clone()
        };
        let kept = matcher.match_pair(&l.view(), &r.view(), &o).unwrap();
        let fresh = match_pair(&l.view(), &r.view(), &o).unwrap();
        assert_eq!(bits(&kept.disparity), bits(&fresh.disparity), "run {i}");
        assert_eq!(bits(&kept.confidence), bits(&fresh.confidence), "run {i}");
        assert!(matcher.retained_bytes() > 0, "run {i}");
    }
    matcher.release();
    assert_eq!(matcher.retained_bytes(), 0);
}
