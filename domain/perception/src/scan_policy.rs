//! When perception asks the ALACS laser scanner for a scan ([dual-arm sec. 5]: the ToF camera
//! serves the typical apples, the laser the hard ones; [alacs sec. 5.2]: the scan localizes to
//! millimetres where the ToF depth is uncertain).
//!
//! An apple qualifies when it is heavily occluded (the visible part of its image disc is below
//! `max_visible_fraction`: the estimate rests on a small, one-sided patch of surface) or when its
//! depth is uncertain (the estimator fell back to its few-point model, or its position
//! confidence is below `min_position_confidence`). The qualifying apples of a frame are asked
//! for most uncertain first (lowest visible fraction times position confidence), at most
//! `max_scans_per_frame` per frame and `max_pending_scans` outstanding, each apple once.

use serde::{Deserialize, Serialize};

/// The laser-scan part of perception's configuration (`[laser]` in the config file).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LaserScanConfig {
    /// Off: no scans are asked for and no track refinement is applied.
    pub enabled: bool,
    /// Ask for a scan when the apple's visible fraction of its image disc is below this.
    pub max_visible_fraction: f64,
    /// Ask for a scan when the estimate's position confidence is below this.
    pub min_position_confidence: f32,
    /// Ask for a scan when the estimator used its few-point fallback.
    pub scan_fallback_estimates: bool,
    /// Scans asked for per frame.
    pub max_scans_per_frame: u32,
    /// Scans asked for and not answered yet (the scanner works one apple at a time, ~1.5 s).
    pub max_pending_scans: u32,
    /// A scan's position further than this from the apple's ToF estimate is refused (the line
    /// fell on another apple), m.
    pub max_refinement_shift_m: f64,
    /// Accept a scan whose answer is its selected single-image candidate (fewer than 3 stripes
    /// agreed, so no sphere was fitted to all of them). Off: such answers are refused (in
    /// `harvest eval laser` they err by 7 mm median, up to several cm, against 0.1 mm for the
    /// fused sphere).
    pub accept_single_image_answers: bool,
    /// A detection continues a track whose last ToF position is within this, m.
    pub track_gate_m: f64,
    /// A track unseen for this long is dropped, ms.
    pub track_timeout_ms: u64,
    /// A scan unanswered for this long is given up, ms.
    pub scan_timeout_ms: u64,
}

impl Default for LaserScanConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            max_visible_fraction: 0.6,
            min_position_confidence: 0.6,
            scan_fallback_estimates: true,
            max_scans_per_frame: 1,
            max_pending_scans: 1,
            max_refinement_shift_m: 0.05,
            accept_single_image_answers: false,
            track_gate_m: 0.03,
            track_timeout_ms: 2_000,
            scan_timeout_ms: 5_000,
        }
    }
}

/// Why a laser-scan setting is unusable.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LaserScanConfigError {
    /// A threshold is not finite or outside its range.
    #[error("perception config: laser.{key} = {value} is not finite or outside {min}..={max}")]
    OutOfRange {
        key: &'static str,
        value: f64,
        min: f64,
        max: f64,
    },
}

impl LaserScanConfig {
    pub fn validate(&self) -> Result<(), LaserScanConfigError> {
        let checks = [
            ("max_visible_fraction", self.max_visible_fraction, 0.0, 1.0),
            (
                "min_position_confidence",
                f64::from(self.min_position_confidence),
                0.0,
                1.0,
            ),
            (
                "max_refinement_shift_m",
                self.max_refinement_shift_m,
                1e-3,
                1.0,
            ),
            ("track_gate_m", self.track_gate_m, 1e-3, 0.5),
            ("track_timeout_ms", self.track_timeout_ms as f64, 1.0, 3.6e6),
            ("scan_timeout_ms", self.scan_timeout_ms as f64, 1.0, 3.6e6),
        ];
        for (key, value, min, max) in checks {
            if !value.is_finite() || value < min || value > max {
                return Err(LaserScanConfigError::OutOfRange {
                    key,
                    value,
                    min,
                    max,
                });
            }
        }
        Ok(())
    }

    /// Whether an apple qualifies for a scan, and how urgently: `Some(priority)` (lower = more
    /// uncertain, asked for first) or `None`.
    pub fn scan_priority(&self, evidence: &ScanEvidence) -> Option<f64> {
        if !self.enabled {
            return None;
        }
        let occluded = evidence.visible_fraction < self.max_visible_fraction;
        let uncertain = evidence.position_confidence < self.min_position_confidence
            || (self.scan_fallback_estimates && evidence.fallback);
        (occluded || uncertain).then(|| {
            evidence.visible_fraction.clamp(0.0, 1.0)
                * f64::from(evidence.position_confidence.clamp(0.0, 1.0))
        })
    }
}

/// What the policy looks at for one apple.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanEvidence {
    /// Visible apple pixels over the pixels of its fitted sphere's image disc.
    pub visible_fraction: f64,
    /// The estimator's geometric confidence, [0, 1].
    pub position_confidence: f32,
    /// The estimator fell back to its few-point model.
    pub fallback: bool,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn evidence(visible_fraction: f64, position_confidence: f32) -> ScanEvidence {
        ScanEvidence {
            visible_fraction,
            position_confidence,
            fallback: false,
        }
    }

    #[test]
    fn occluded_or_uncertain_apples_qualify_most_uncertain_first() {
        let config = LaserScanConfig::default();
        assert_eq!(config.scan_priority(&evidence(0.9, 0.9)), None);
        let occluded = config.scan_priority(&evidence(0.3, 0.9)).expect("occluded");
        let uncertain = config
            .scan_priority(&evidence(0.9, 0.4))
            .expect("uncertain");
        assert!((occluded - 0.27).abs() < 1e-6 && (uncertain - 0.36).abs() < 1e-6);
        let fallback = ScanEvidence {
            fallback: true,
            ..evidence(0.9, 0.9)
        };
        assert!(config.scan_priority(&fallback).is_some());
        let ignore_fallback = LaserScanConfig {
            scan_fallback_estimates: false,
            ..config
        };
        assert_eq!(ignore_fallback.scan_priority(&fallback), None);
        let off = LaserScanConfig {
            enabled: false,
            ..config
        };
        assert_eq!(off.scan_priority(&evidence(0.1, 0.1)), None);
    }

    #[test]
    fn config_parses_and_rejects_bad_values() {
        let config: LaserScanConfig =
            toml::from_str("enabled = false\nmax_scans_per_frame = 3").expect("parse");
        assert!(!config.enabled && config.max_scans_per_frame == 3);
        assert!(toml::from_str::<LaserScanConfig>("max_scans = 3").is_err());
        let bad = LaserScanConfig {
            max_visible_fraction: f64::NAN,
            ..LaserScanConfig::default()
        };
        assert!(matches!(
            bad.validate(),
            Err(LaserScanConfigError::OutOfRange {
                key: "max_visible_fraction",
                ..
            })
        ));
        assert!(LaserScanConfig::default().validate().is_ok());
    }
}
