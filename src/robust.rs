//! Robust-statistics pieces shared by the fits that must ignore outliers (the mesh's local
//! planes, the stereo matcher's alignment fit).

/// Tukey's biweight cut-off in units of the noise's standard deviation (95 % efficiency under
/// Gaussian noise).
pub(crate) const TUKEY_C: f64 = 4.685;

/// Standard deviation of Gaussian noise per unit of median absolute deviation.
pub(crate) const MAD_TO_SIGMA: f64 = 1.4826;

/// Tukey's biweight `(1 − (r/c)²)²` for a residual `r` with cut-off `c`; 0 from `|r| ≥ c` on.
pub(crate) fn tukey(r: f64, c: f64) -> f64 {
    let t = r / c;
    if t.abs() >= 1.0 {
        0.0
    } else {
        let s = 1.0 - t * t;
        s * s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tukey_weighs_one_at_zero_and_nothing_past_the_cut() {
        assert_eq!(tukey(0.0, 2.0), 1.0);
        assert!((tukey(1.0, 2.0) - 0.5625).abs() < 1e-12);
        assert_eq!(tukey(-2.0, 2.0), 0.0);
        assert_eq!(tukey(5.0, 2.0), 0.0);
    }
}
