//! Middlebury's scoring rules (its SDK, as `shared/data/README.md` states them): pixels whose truth
//! is unknown are skipped; the estimate is clipped to `[0, ndisp]`; `bad T` is the percentage of
//! evaluated pixels whose absolute error exceeds `T` pixels, pixels without an estimate counting as
//! bad ("dense" scoring); `nonocc` evaluates the pixels the mask marks visible in both views (255),
//! `all` every pixel with a known truth; `avgerr` is the mean absolute error over the pixels that
//! have an estimate.

use crate::error::{Error, Result};
use crate::image::Raster;

/// Error thresholds of `bad`, pixels.
pub const THRESHOLDS: [f32; 3] = [0.5, 1.0, 2.0];

/// Scores over one set of pixels.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct RegionScore {
    /// Percent of pixels with error above each of [`THRESHOLDS`] (holes count as bad).
    pub bad: [f64; 3],
    /// Percent of pixels without an estimate.
    pub invalid: f64,
    /// Mean absolute error over pixels with an estimate, pixels.
    pub avgerr: f64,
    /// Number of pixels evaluated.
    pub pixels: usize,
}

/// Scores of one disparity map.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Scores {
    /// Pixels visible in both views.
    pub nonocc: RegionScore,
    /// Every pixel with a known truth.
    pub all: RegionScore,
}

/// Scores `estimate` (NaN = no estimate) against `truth` (NaN = unknown) with the occlusion mask
/// (255 = visible in both views).
///
/// # Errors
/// `SizeMismatch` when the three rasters differ in size; `InvalidArgument` for a bad `ndisp`.
pub fn score(
    estimate: &Raster<f32>,
    truth: &Raster<f32>,
    mask: &Raster<u8>,
    ndisp: f32,
) -> Result<Scores> {
    let size = |r: (usize, usize)| format!("{}x{}", r.0, r.1);
    let (e, t, m) = (
        (estimate.width(), estimate.height()),
        (truth.width(), truth.height()),
        (mask.width(), mask.height()),
    );
    if e != t || e != m {
        return Err(Error::SizeMismatch(format!(
            "scoring: estimate {}, truth {}, mask {} differ",
            size(e),
            size(t),
            size(m)
        )));
    }
    if !(ndisp.is_finite() && ndisp > 0.0) {
        return Err(Error::invalid(format!(
            "scoring: ndisp {ndisp} must be > 0"
        )));
    }
    #[derive(Default)]
    struct Acc {
        bad: [usize; 3],
        holes: usize,
        err_sum: f64,
        with_estimate: usize,
        n: usize,
    }
    let add = |acc: &mut Acc, est: f32, gt: f32| {
        acc.n += 1;
        if est.is_nan() {
            acc.holes += 1;
            for b in &mut acc.bad {
                *b += 1;
            }
            return;
        }
        let err = (est.clamp(0.0, ndisp) - gt).abs();
        acc.err_sum += err as f64;
        acc.with_estimate += 1;
        for (b, &th) in acc.bad.iter_mut().zip(&THRESHOLDS) {
            if err > th {
                *b += 1;
            }
        }
    };
    let (mut nonocc, mut all) = (Acc::default(), Acc::default());
    for ((&est, &gt), &mk) in estimate
        .pixels()
        .iter()
        .zip(truth.pixels())
        .zip(mask.pixels())
    {
        if !gt.is_finite() {
            continue;
        }
        add(&mut all, est, gt);
        if mk == 255 {
            add(&mut nonocc, est, gt);
        }
    }
    let finish = |a: Acc| {
        let pct = |v: usize| {
            if a.n == 0 {
                0.0
            } else {
                100.0 * v as f64 / a.n as f64
            }
        };
        RegionScore {
            bad: [pct(a.bad[0]), pct(a.bad[1]), pct(a.bad[2])],
            invalid: pct(a.holes),
            avgerr: if a.with_estimate == 0 {
                0.0
            } else {
                a.err_sum / a.with_estimate as f64
            },
            pixels: a.n,
        }
    };
    Ok(Scores {
        nonocc: finish(nonocc),
        all: finish(all),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scores_follow_the_middlebury_rules() {
        // 4 pixels: exact, 0.7 off, hole, unknown truth; the last is occluded (mask 128).
        let est = Raster::from_vec(5, 1, vec![10.0, 10.7, f32::NAN, 3.0, 200.0]);
        let gt = Raster::from_vec(5, 1, vec![10.0, 10.0, 10.0, f32::NAN, 60.0]);
        let mask = Raster::from_vec(5, 1, vec![255, 255, 255, 255, 128]);
        let s = score(&est, &gt, &mask, 64.0).unwrap();
        assert_eq!(s.nonocc.pixels, 3);
        assert!((s.nonocc.bad[0] - 200.0 / 3.0).abs() < 1e-9);
        assert!((s.nonocc.bad[1] - 100.0 / 3.0).abs() < 1e-9);
        assert!((s.nonocc.invalid - 100.0 / 3.0).abs() < 1e-9);
        assert!((s.nonocc.avgerr - 0.35).abs() < 1e-6);
        // All: 200 is clipped to 64, 4 px off; bad 2.0 = the hole and that pixel.
        assert_eq!(s.all.pixels, 4);
        assert!((s.all.bad[2] - 50.0).abs() < 1e-9);
        assert!((s.all.avgerr - (0.7 + 4.0) / 3.0).abs() < 1e-6);
        assert!(score(&est, &Raster::filled(4, 1, 0.0), &mask, 64.0).is_err());
        assert!(score(&est, &gt, &mask, f32::NAN).is_err());
    }
}
