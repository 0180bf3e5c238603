//! Camera calibration and the disparity ↔ depth relation.
//!
//! Depth follows DESIGN.md: `Z = f·B / (d + doffs)`, metres, with `f` in pixels, `B` the baseline
//! in metres and `doffs` the x difference of the two principal points (Middlebury's `doffs`).

use std::path::Path;

use crate::error::{Error, Result};

/// Calibration of a rectified stereo pair.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StereoCalibration {
    /// Focal length in pixels (both axes: rectified images have square pixels).
    pub focal_px: f64,
    /// Principal point of the left camera, pixels (x right, y down).
    pub cx: f64,
    /// Principal point of the left camera, pixels.
    pub cy: f64,
    /// Distance between the two camera centres, metres.
    pub baseline_m: f64,
    /// `cx_right − cx_left` in pixels (0 for a symmetric rig).
    pub doffs: f64,
    /// Largest disparity worth searching, pixels, when the calibration says (Middlebury `ndisp`).
    pub max_disparity: Option<u32>,
}

impl StereoCalibration {
    /// A calibration from focal length and baseline alone, principal point at the image centre.
    ///
    /// # Errors
    /// `InvalidArgument` when a value is not finite and positive.
    pub fn from_focal_baseline(
        focal_px: f64,
        baseline_m: f64,
        width: u32,
        height: u32,
    ) -> Result<Self> {
        let c = StereoCalibration {
            focal_px,
            cx: width as f64 / 2.0,
            cy: height as f64 / 2.0,
            baseline_m,
            doffs: 0.0,
            max_disparity: None,
        };
        c.validate()?;
        Ok(c)
    }

    /// Checks that focal length and baseline are finite and positive and the offsets finite.
    ///
    /// # Errors
    /// `InvalidArgument` naming the bad value.
    pub fn validate(&self) -> Result<()> {
        let positive = |name: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(Error::invalid(format!(
                    "calibration: {name} must be finite and > 0, got {v}"
                )))
            }
        };
        positive("focal length (px)", self.focal_px)?;
        positive("baseline (m)", self.baseline_m)?;
        for (name, v) in [("cx", self.cx), ("cy", self.cy), ("doffs", self.doffs)] {
            if !v.is_finite() {
                return Err(Error::invalid(format!(
                    "calibration: {name} must be finite, got {v}"
                )));
            }
        }
        Ok(())
    }

    /// Parses a Middlebury `calib.txt` (`cam0=[f 0 cx; 0 f cy; 0 0 1]`, `doffs`, `baseline` in mm,
    /// `ndisp`; other keys ignored).
    ///
    /// # Errors
    /// `Format` for a missing or malformed key, `InvalidArgument` for non-positive values.
    pub fn parse_middlebury(text: &str) -> Result<Self> {
        let mut cam0 = None;
        let mut doffs = None;
        let mut baseline_mm = None;
        let mut ndisp = None;
        for line in text.lines() {
            let Some((key, value)) = line.split_once('=') else {
                continue;
            };
            let value = value.trim();
            match key.trim() {
                "cam0" => cam0 = Some(parse_matrix(value)?),
                "doffs" => doffs = Some(parse_number("doffs", value)?),
                "baseline" => baseline_mm = Some(parse_number("baseline", value)?),
                "ndisp" => ndisp = Some(parse_number("ndisp", value)?),
                _ => {}
            }
        }
        let cam0 = cam0.ok_or_else(|| Error::format("calib.txt: missing cam0"))?;
        let baseline_mm =
            baseline_mm.ok_or_else(|| Error::format("calib.txt: missing baseline"))?;
        let ndisp = match ndisp {
            Some(n) if n.is_finite() && n >= 1.0 && n <= u32::MAX as f64 => Some(n as u32),
            Some(n) => {
                return Err(Error::invalid(format!(
                    "calib.txt: ndisp {n} is not a positive integer"
                )))
            }
            None => None,
        };
        let c = StereoCalibration {
            focal_px: cam0[0],
            cx: cam0[2],
            cy: cam0[5],
            baseline_m: baseline_mm / 1000.0,
            doffs: doffs.unwrap_or(0.0),
            max_disparity: ndisp,
        };
        c.validate()?;
        Ok(c)
    }

    /// Reads and parses a Middlebury `calib.txt`.
    ///
    /// # Errors
    /// `Io`, or as [`StereoCalibration::parse_middlebury`].
    pub fn load_middlebury(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Self::parse_middlebury(&text).map_err(|e| match e {
            Error::Format(m) => Error::Format(format!("{}: {m}", path.display())),
            other => other,
        })
    }

    /// Depth in metres of a disparity in pixels; NaN for no estimate or a non-positive `d + doffs`.
    pub fn depth_from_disparity(&self, disparity: f32) -> f32 {
        let denominator = disparity as f64 + self.doffs;
        if disparity.is_nan() || denominator <= 0.0 {
            f32::NAN
        } else {
            (self.focal_px * self.baseline_m / denominator) as f32
        }
    }

    /// Disparity in pixels of a depth in metres (inverse of [`Self::depth_from_disparity`]).
    pub fn disparity_from_depth(&self, depth_m: f32) -> f32 {
        if depth_m.is_nan() || depth_m <= 0.0 {
            f32::NAN
        } else {
            (self.focal_px * self.baseline_m / depth_m as f64 - self.doffs) as f32
        }
    }
}

fn parse_number(key: &str, value: &str) -> Result<f64> {
    value
        .parse::<f64>()
        .map_err(|_| Error::format(format!("calib.txt: {key}={value:?} is not a number")))
}

fn parse_matrix(value: &str) -> Result<[f64; 9]> {
    let inner = value.trim_start_matches('[').trim_end_matches(']');
    let numbers: Vec<f64> = inner
        .split(|c: char| c == ';' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .map(|s| parse_number("cam0", s))
        .collect::<Result<_>>()?;
    numbers.try_into().map_err(|v: Vec<f64>| {
        Error::format(format!(
            "calib.txt: cam0 has {} numbers, expected 9",
            v.len()
        ))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const ARTL: &str = "cam0=[1870 0 297; 0 1870 277; 0 0 1]\ncam1=[1870 0 397; 0 1870 277; 0 0 1]\ndoffs=100\nbaseline=111.53\nwidth=694\nheight=554\nndisp=256\nisint=0\nvmin=1\nvmax=200\n";

    #[test]
    fn parses_middlebury_calibration() {
        let c = StereoCalibration::parse_middlebury(ARTL).unwrap();
        assert_eq!(c.focal_px, 1870.0);
        assert_eq!((c.cx, c.cy), (297.0, 277.0));
        assert!((c.baseline_m - 0.11153).abs() < 1e-12);
        assert_eq!(c.doffs, 100.0);
        assert_eq!(c.max_disparity, Some(256));
    }

    #[test]
    fn depth_and_disparity_are_inverse() {
        let c = StereoCalibration::parse_middlebury(ARTL).unwrap();
        let z = c.depth_from_disparity(50.0);
        // Z = f·B/(d + doffs) = 1870 · 0.11153 / 150
        assert!((z as f64 - 1870.0 * 0.11153 / 150.0).abs() < 1e-6);
        assert!((c.disparity_from_depth(z) - 50.0).abs() < 1e-3);
        assert!(c.depth_from_disparity(f32::NAN).is_nan());
        assert!(c.depth_from_disparity(-100.0).is_nan());
    }

    #[test]
    fn rejects_bad_calibration() {
        assert!(matches!(
            StereoCalibration::parse_middlebury("doffs=1"),
            Err(Error::Format(_))
        ));
        assert!(StereoCalibration::parse_middlebury(
            &ARTL.replace("baseline=111.53", "baseline=-1")
        )
        .is_err());
        assert!(
            StereoCalibration::parse_middlebury(&ARTL.replace("1870 0 297", "nan 0 297")).is_err()
        );
        assert!(
            StereoCalibration::parse_middlebury(&ARTL.replace("0 0 1]\ncam1", "0]\ncam1")).is_err()
        );
        assert!(StereoCalibration::from_focal_baseline(f64::INFINITY, 0.1, 10, 10).is_err());
        assert!(StereoCalibration::from_focal_baseline(500.0, 0.0, 10, 10).is_err());
    }
}
