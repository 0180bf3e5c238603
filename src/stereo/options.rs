//! Every knob of the stereo matcher, and the three documented presets.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// Pixel matching cost.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CostKind {
    /// Hamming distance of census transforms (robust to exposure and lighting changes).
    Census,
    /// Sum of absolute grey-level differences over a square block (the thesis, Algorithm 1).
    Sad,
}

/// How matching costs are aggregated before the winner is picked.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Aggregation {
    /// Semi-global matching along 8 paths (eq. 3.3–3.4).
    Sgm8,
    /// Semi-global matching along the 4 horizontal and vertical paths.
    Sgm4,
    /// The thesis' scanline dynamic programming with back-tracking (Algorithms 1–2).
    ScanlineDp,
}

/// Sub-pixel refinement of the integer winner.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Subpixel {
    /// Integer disparities only.
    None,
    /// Parabola through the best cost and its two neighbours (the thesis).
    Parabola,
    /// Symmetric V through the three costs; less biased towards integers for L1-like costs.
    Equiangular,
}

/// A named, documented set of options.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Preset {
    /// As `Balanced` with census 5×5 and one smoothing pass.
    Fast,
    /// Census 7×7, 4-path SGM; a half-size pass narrows each pixel's search to 16 disparities
    /// and measures the pair's residual vertical misalignment, undone before the full-size
    /// match; equiangular sub-pixel, L/R check, uniqueness 5 %, speckles < 100 px, background
    /// fill, 3 passes of edge-aware smoothing. The default of the matcher on its own, chosen for
    /// its run time: on Middlebury, `Quality`'s 8 paths, wider census and window and local fit
    /// buy half a point of bad 0.5 px for nearly twice the time (docs/stereo-eval.md, stop 39).
    Balanced,
    /// Census 9×7, 8-path SGM, a window of 32 disparities after the half-size pass, 5×5 local
    /// fit on the grey levels; otherwise as `Balanced`. What [`crate::scene::Scene`] matches
    /// with: on noisy photographs its sub-pixel precision is what keeps planes and placements
    /// right (docs/stereo-eval.md, stop 39).
    Quality,
}

impl Preset {
    /// All presets, fastest first.
    pub const ALL: [Preset; 3] = [Preset::Fast, Preset::Balanced, Preset::Quality];

    /// The lower-case name (`fast`, `balanced`, `quality`).
    pub fn name(self) -> &'static str {
        match self {
            Preset::Fast => "fast",
            Preset::Balanced => "balanced",
            Preset::Quality => "quality",
        }
    }
}

impl fmt::Display for Preset {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Preset {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "fast" => Ok(Preset::Fast),
            "balanced" => Ok(Preset::Balanced),
            "quality" => Ok(Preset::Quality),
            other => Err(Error::invalid(format!(
                "unknown stereo preset {other:?} (expected fast, balanced or quality)"
            ))),
        }
    }
}

/// Options of [`super::match_pair`]. `Default` is the `balanced` preset.
///
/// Costs live on a 0–255 scale whatever [`CostKind`] is chosen, so `p1`/`p2` mean the same for both.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct StereoOptions {
    /// Largest disparity searched, pixels; the search covers `0..=max_disparity`. Must be ≥ 1 and
    /// less than the image width.
    pub max_disparity: u32,
    /// Pixel matching cost.
    pub cost: CostKind,
    /// Census window half-width and half-height (window `(2rx+1)×(2ry+1)`, at most 63 neighbours).
    pub census_radius: (u32, u32),
    /// SAD block half-size (block `(2r+1)²`; the thesis uses 4).
    pub sad_radius: u32,
    /// Aggregation method.
    pub aggregation: Aggregation,
    /// SGM penalty for a disparity change of one pixel between path neighbours (cost units).
    pub p1: u16,
    /// SGM penalty for larger changes (cost units); clamped internally so sums cannot overflow.
    pub p2: u16,
    /// Makes P2 smaller across image edges: `P2' = max(P1, P2 / (1 + |ΔI| / s))` with `s` this
    /// value in grey levels; 0 keeps P2 constant.
    pub p2_gradient_scale: f32,
    /// Smoothness penalty of the scanline DP per pixel of disparity change (cost units).
    pub dp_penalty: f32,
    /// Sub-pixel refinement.
    pub subpixel: Subpixel,
    /// After sub-pixel: refine each estimate on the grey levels of a `(2r+1)²` window (Lucas–Kanade
    /// in one dimension, see `refine::refine_locally`); 0 = off.
    pub local_refinement_radius: u32,
    /// Left/right consistency: largest allowed difference in pixels; `None` skips the check.
    pub lr_max_diff: Option<u32>,
    /// Uniqueness margin in percent (0 = off): the best cost must beat every non-adjacent
    /// disparity by this margin.
    pub uniqueness: u32,
    /// Connected regions smaller than this many pixels are removed (0 = off).
    pub speckle_size: u32,
    /// Largest disparity step inside one speckle region, pixels.
    pub speckle_range: f32,
    /// Fill pixels without an estimate (occlusions take the background side). `false` keeps NaN.
    pub fill: bool,
    /// Passes of the edge-aware cascaded smoothing (0 = off).
    pub smoothing_passes: u32,
    /// Number of half-resolution levels matched first to narrow the search (0 = full search).
    pub coarse_levels: u32,
    /// Disparities searched per pixel at each finer level when `coarse_levels > 0`.
    pub coarse_window: u32,
    /// Estimate and undo a global vertical offset (±8 px) and rotation (≤ 1°) of the right view.
    pub correct_misalignment: bool,
    /// Measure the residual vertical offset and rotation of a nearly rectified pair (under
    /// ±2 px) from the half-size level's disparities and undo it before the full-size match
    /// (`alignment::estimate_residual`); without coarse-to-fine a half-size match is made for it.
    pub refine_alignment: bool,
    /// Scale P1 and P2 up for a noisy pair (census with a half-size level only): by how much the
    /// median cost of the half-size level's matches has closed the gap to the cost of unrelated
    /// pixels, against a clean pair's (`noise::penalty_scale`, at most 8×). Clean photographs
    /// keep the penalties as given. Off in every preset: on the noisy built-in renders it helped
    /// some figures and hurt others (docs/stereo-eval.md, stop 25).
    pub noise_adaptive_penalties: bool,
}

impl Default for StereoOptions {
    fn default() -> Self {
        Self::preset(Preset::Balanced)
    }
}

impl StereoOptions {
    /// The options of a preset (`max_disparity` 64; set it for your data).
    pub fn preset(preset: Preset) -> Self {
        let balanced = StereoOptions {
            max_disparity: 64,
            cost: CostKind::Census,
            census_radius: (3, 3),
            sad_radius: 4,
            aggregation: Aggregation::Sgm4,
            p1: 24,
            p2: 320,
            p2_gradient_scale: 16.0,
            dp_penalty: 4.0,
            subpixel: Subpixel::Equiangular,
            local_refinement_radius: 0,
            lr_max_diff: Some(1),
            uniqueness: 5,
            speckle_size: 100,
            speckle_range: 1.0,
            fill: true,
            smoothing_passes: 3,
            coarse_levels: 1,
            coarse_window: 16,
            correct_misalignment: false,
            refine_alignment: true,
            noise_adaptive_penalties: false,
        };
        match preset {
            Preset::Balanced => balanced,
            Preset::Fast => StereoOptions {
                census_radius: (2, 2),
                smoothing_passes: 1,
                ..balanced
            },
            Preset::Quality => StereoOptions {
                census_radius: (4, 3),
                aggregation: Aggregation::Sgm8,
                local_refinement_radius: 2,
                coarse_window: 32,
                ..balanced
            },
        }
    }

    /// The thesis' method: SAD blocks and scanline DP, parabola sub-pixel.
    pub fn thesis() -> Self {
        StereoOptions {
            cost: CostKind::Sad,
            aggregation: Aggregation::ScanlineDp,
            subpixel: Subpixel::Parabola,
            ..Self::default()
        }
    }

    /// These options with the fields of a JSON object put over them, for example
    /// `{"smoothing_passes": 2, "p2": 400}` (field names as in this struct, enums in snake case:
    /// `"aggregation": "sgm4"`). Fields left out keep their value; the result is not validated
    /// (that needs the image width, see [`StereoOptions::validate`]).
    ///
    /// # Errors
    /// `InvalidArgument` when `json` is not an object of known fields with values of the right
    /// type.
    pub fn with_json(&self, json: &str) -> Result<Self> {
        let bad = |e: serde_json::Error| Error::invalid(format!("stereo options {json:?}: {e}"));
        let patch: serde_json::Value = serde_json::from_str(json).map_err(bad)?;
        let Some(patch) = patch.as_object() else {
            return Err(Error::invalid(format!(
                "stereo options {json:?}: expected a JSON object of option fields"
            )));
        };
        let mut merged = serde_json::to_value(self).map_err(bad)?;
        if let Some(fields) = merged.as_object_mut() {
            for (key, value) in patch {
                if !fields.contains_key(key) {
                    return Err(Error::invalid(format!(
                        "stereo options: unknown field {key:?}"
                    )));
                }
                fields.insert(key.clone(), value.clone());
            }
        }
        serde_json::from_value(merged).map_err(bad)
    }

    /// Checks every option against the image width.
    ///
    /// # Errors
    /// `InvalidArgument` naming the option.
    pub fn validate(&self, width: u32) -> Result<()> {
        if self.max_disparity == 0 {
            return Err(Error::invalid("max_disparity must be at least 1"));
        }
        if self.max_disparity >= width {
            return Err(Error::invalid(format!(
                "max_disparity {} must be less than the image width {width}",
                self.max_disparity
            )));
        }
        if self.max_disparity > u16::MAX as u32 / 2 {
            return Err(Error::invalid(format!(
                "max_disparity {} exceeds {}",
                self.max_disparity,
                u16::MAX / 2
            )));
        }
        let (rx, ry) = self.census_radius;
        if rx == 0 && ry == 0 || (2 * rx + 1) * (2 * ry + 1) > 64 {
            return Err(Error::invalid(format!(
                "census_radius {rx}×{ry}: the window must have between 1 and 63 neighbours"
            )));
        }
        if self.sad_radius > 32 {
            return Err(Error::invalid(format!(
                "sad_radius {} exceeds 32",
                self.sad_radius
            )));
        }
        if self.p1 == 0 || self.p2 < self.p1 {
            return Err(Error::invalid(format!(
                "SGM penalties need 0 < p1 ≤ p2, got p1 = {}, p2 = {}",
                self.p1, self.p2
            )));
        }
        let finite_nonneg = |name: &str, v: f32| {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                Err(Error::invalid(format!(
                    "{name} must be finite and ≥ 0, got {v}"
                )))
            }
        };
        finite_nonneg("p2_gradient_scale", self.p2_gradient_scale)?;
        finite_nonneg("dp_penalty", self.dp_penalty)?;
        finite_nonneg("speckle_range", self.speckle_range)?;
        if self.uniqueness >= 100 {
            return Err(Error::invalid(format!(
                "uniqueness {} % must be below 100",
                self.uniqueness
            )));
        }
        if self.local_refinement_radius > 4 {
            return Err(Error::invalid(format!(
                "local_refinement_radius {} exceeds 4",
                self.local_refinement_radius
            )));
        }
        if self.coarse_levels > 4 {
            return Err(Error::invalid(format!(
                "coarse_levels {} exceeds 4",
                self.coarse_levels
            )));
        }
        if self.coarse_levels > 0 && self.coarse_window < 4 {
            return Err(Error::invalid(format!(
                "coarse_window {} must be at least 4",
                self.coarse_window
            )));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_parse_and_validate() {
        for p in Preset::ALL {
            assert_eq!(p.name().parse::<Preset>().unwrap(), p);
            StereoOptions::preset(p).validate(640).unwrap();
        }
        assert!("medium".parse::<Preset>().is_err());
        assert_eq!(
            StereoOptions::default(),
            StereoOptions::preset(Preset::Balanced)
        );
        StereoOptions::thesis().validate(640).unwrap();
    }

    #[test]
    fn options_round_trip_through_json() {
        let o = StereoOptions::preset(Preset::Fast);
        let json = serde_json::to_string(&o).unwrap();
        let back: StereoOptions = serde_json::from_str(&json).unwrap();
        assert_eq!(back, o);
        // Missing fields take the default preset's values.
        let partial: StereoOptions = serde_json::from_str(r#"{"max_disparity": 32}"#).unwrap();
        assert_eq!(partial.max_disparity, 32);
        assert_eq!(partial.p1, StereoOptions::default().p1);
    }

    #[test]
    fn json_fields_go_over_the_preset_and_unknown_ones_are_refused() {
        let fast = StereoOptions::preset(Preset::Fast);
        let o = fast
            .with_json(r#"{"smoothing_passes": 5, "aggregation": "sgm8"}"#)
            .unwrap();
        assert_eq!(o.smoothing_passes, 5);
        assert_eq!(o.aggregation, Aggregation::Sgm8);
        assert_eq!(o.census_radius, fast.census_radius);
        for bad in [r#"{"smothing": 1}"#, "[1, 2]", r#"{"p1": "high"}"#, "{"] {
            let e = fast.with_json(bad).unwrap_err().to_string();
            assert!(e.contains("stereo options"), "{bad}: {e}");
        }
    }

    #[test]
    fn bad_options_are_named() {
        let o = StereoOptions::default();
        let err = |o: StereoOptions| o.validate(100).unwrap_err().to_string();
        assert!(err(StereoOptions {
            max_disparity: 0,
            ..o.clone()
        })
        .contains("max_disparity"));
        assert!(err(StereoOptions {
            max_disparity: 100,
            ..o.clone()
        })
        .contains("width"));
        assert!(err(StereoOptions {
            p1: 10,
            p2: 5,
            ..o.clone()
        })
        .contains("p2"));
        assert!(err(StereoOptions {
            census_radius: (5, 5),
            ..o.clone()
        })
        .contains("census"));
        assert!(err(StereoOptions {
            dp_penalty: f32::NAN,
            ..o.clone()
        })
        .contains("dp_penalty"));
    }
}
