//! The evaluation function that picks the final apple position among the interval scan's
//! candidates ([alacs sec. 3], step 3: "a holistic evaluation function"; the paper gives
//! no formula, so this is our design).
//!
//! Each candidate is scored by its *predicted standard error*
//! ([`PositionCandidate::predicted_sigma_m`]), which folds in everything that makes one image
//! better than another:
//! - **stripe length and noise**: fewer or noisier points on the apple (leaf occlusion, a line
//!   near the apple's edge) widen the circle fit's covariance;
//! - **geometry**: the centre sits `h = sqrt(R^2 - r^2)` off the plane; as the plane nears the
//!   centre (`r -> R`) errors in `r` and in the apple radius `R` are amplified by `R / h`;
//! - **side ambiguity**: a plane within the rough localisation's error of the centre cannot tell
//!   which side the centre is on, which costs `h` itself.
//!
//! The candidate with the smallest predicted error wins; ties go to the earlier image (the one
//! taken nearest to the RGB-D estimate's left-half start).

use crate::candidate::PositionCandidate;

/// Index of the candidate with the smallest predicted standard error among one entry per image
/// (`None` for an image without a candidate); `None` when no image gave a candidate.
pub fn select_candidate<'a>(
    candidates: impl IntoIterator<Item = Option<&'a PositionCandidate>>,
) -> Option<usize> {
    let mut best: Option<(usize, f64)> = None;
    for (index, candidate) in candidates.into_iter().enumerate() {
        let Some(candidate) = candidate else {
            continue;
        };
        let score = candidate.predicted_sigma_m;
        if !score.is_finite() {
            continue;
        }
        if best.is_none_or(|(_, best_score)| score < best_score) {
            best = Some((index, score));
        }
    }
    best.map(|(index, _)| index)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::candidate::CandidateError;

    fn select(candidates: &[Result<PositionCandidate, CandidateError>]) -> Option<usize> {
        select_candidate(candidates.iter().map(|c| c.as_ref().ok()))
    }

    fn candidate(predicted_sigma_m: f64) -> PositionCandidate {
        PositionCandidate {
            slide_position_m: 0.0,
            centre_in_camera_m: [0.0, 0.0, 1.0],
            circle_centre_in_camera_m: [0.0, 0.0, 1.0],
            circle_radius_m: 0.03,
            apple_radius_m: 0.04,
            plane_to_centre_m: 0.02,
            points_used: 50,
            points_rejected: 0,
            fit_rms_m: 1e-4,
            predicted_sigma_m,
        }
    }

    #[test]
    fn smallest_predicted_error_wins_and_failures_are_skipped() {
        let candidates = vec![
            Ok(candidate(3e-3)),
            Err(CandidateError::TooFewPoints {
                found: 2,
                needed: 12,
            }),
            Ok(candidate(1e-3)),
            Ok(candidate(1e-3)),
            Ok(candidate(f64::NAN)),
        ];
        assert_eq!(select(&candidates), Some(2));
        assert_eq!(select(&candidates[..2]), Some(0));
        assert_eq!(select(&candidates[1..2]), None);
        assert_eq!(select(&[]), None);
    }
}
