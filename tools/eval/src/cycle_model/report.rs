//! The numbers the cycle model is for: Fig. 12 (ideal per-apple cycle time of each policy) and
//! the single-arm vs. dual-arm time per attempt with field failure rates (section 4.2).

use super::{CycleEpisode, CycleModelError, run_episode, seconds};
use harvest_vacuum::policy::{PolicyKind, new_policy};

/// One bar of Fig. 12.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fig12Row {
    /// The policy.
    pub policy: PolicyKind,
    /// Mean interval between releases once the timeline is periodic, s per apple (the
    /// quantity of Fig. 12).
    pub steady_state_s_per_apple: f64,
    /// Whole episode, start-up included, s per apple.
    pub makespan_s_per_apple: f64,
    /// The value the paper reads off Fig. 12, s per apple.
    pub paper_s_per_apple: f64,
}

/// Run the ideal episode of Fig. 12 with `apples_per_arm` apples per arm under each policy.
pub fn fig12(apples_per_arm: u32) -> Result<Vec<Fig12Row>, CycleModelError> {
    let episode = CycleEpisode::ideal(apples_per_arm);
    PolicyKind::ALL
        .into_iter()
        .zip([4.5, 2.5, 2.25])
        .map(|(policy, paper_s_per_apple)| {
            let r = run_episode(new_policy(policy).as_ref(), &episode)?;
            Ok(Fig12Row {
                policy,
                steady_state_s_per_apple: steady_state_interval_ns(&r.release_times_ns)
                    .map_or(f64::NAN, seconds),
                makespan_s_per_apple: r.seconds_per_apple().unwrap_or(f64::NAN),
                paper_s_per_apple,
            })
        })
        .collect()
}

/// Mean interval between sorted release times over the second half of the episode, using an
/// even number of intervals so that a two-arm pattern (short gap, long gap) averages out, ns.
/// `None` with fewer than three releases.
pub fn steady_state_interval_ns(release_times_ns: &[u64]) -> Option<u64> {
    let n = release_times_ns.len();
    if n < 3 {
        return None;
    }
    let k = ((n / 2) & !1).max(2);
    let span = release_times_ns[n - 1] - release_times_ns[n - 1 - k];
    Some(span / k as u64)
}

/// Single arm vs. both arms on the same kind of attempts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SingleDualComparison {
    /// The policy of the dual-arm run (the single-arm run uses the 2024 policy; with one arm
    /// the policies differ only in whether a failed attempt skips the release).
    pub policy: PolicyKind,
    /// Single arm, s per attempt.
    pub single_s_per_attempt: f64,
    /// Both arms, s per attempt.
    pub dual_s_per_attempt: f64,
    /// `1 - dual / single`, percent (field: 28 %).
    pub reduction_pct: f64,
    /// Harvested / attempts in the dual-arm run.
    pub dual_success_rate: f64,
}

/// Time per attempt of one arm doing `attempts` attempts alone vs. two arms sharing them under
/// `policy`, with the failure rates, jitter and seed of `base` (its `attempts_per_arm` is
/// ignored).
pub fn single_vs_dual(
    policy: PolicyKind,
    base: &CycleEpisode,
    attempts: u32,
) -> Result<SingleDualComparison, CycleModelError> {
    let single = CycleEpisode {
        attempts_per_arm: [attempts, 0],
        record_trace: false,
        ..*base
    };
    let dual = CycleEpisode {
        attempts_per_arm: [attempts / 2, attempts - attempts / 2],
        record_trace: false,
        ..*base
    };
    let single = run_episode(new_policy(PolicyKind::V2024).as_ref(), &single)?;
    let dual = run_episode(new_policy(policy).as_ref(), &dual)?;
    let single_s = single.seconds_per_attempt().unwrap_or(f64::NAN);
    let dual_s = dual.seconds_per_attempt().unwrap_or(f64::NAN);
    Ok(SingleDualComparison {
        policy,
        single_s_per_attempt: single_s,
        dual_s_per_attempt: dual_s,
        reduction_pct: 100.0 * (1.0 - dual_s / single_s),
        dual_success_rate: f64::from(dual.harvested) / f64::from(dual.attempts.max(1)),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cycle_model::FailureRates;

    #[test]
    fn fig12_rows_match_the_paper() {
        for row in fig12(20).expect("runs") {
            assert!(
                (row.steady_state_s_per_apple - row.paper_s_per_apple).abs() < 1e-9,
                "{row:?}"
            );
            // Start-up makes the whole-episode figure a little worse, never better.
            assert!(row.makespan_s_per_apple >= row.steady_state_s_per_apple - 1e-9);
        }
    }

    #[test]
    fn steady_state_interval_known_answers() {
        assert_eq!(steady_state_interval_ns(&[1, 2]), None);
        assert_eq!(steady_state_interval_ns(&[0, 10, 20, 30]), Some(10));
        // Two arms 1 apart, period 10: pairs (0,1), (10,11), ...: mean 5.
        let t: Vec<u64> = (0..10).flat_map(|k| [10 * k, 10 * k + 1]).collect();
        assert_eq!(steady_state_interval_ns(&t), Some(5));
    }

    #[test]
    fn dual_arm_2024_beats_single_arm_with_field_failures() {
        let mut base = CycleEpisode::ideal(0);
        base.failures = FailureRates::field_2024();
        base.movement_jitter = 0.5;
        base.seed = 5;
        let c = single_vs_dual(PolicyKind::V2024, &base, 2000).expect("runs");
        assert!(c.dual_s_per_attempt < c.single_s_per_attempt);
        // Success rate is the drawn one: 1 - 0.274 within sampling error (5 sigma ~ 0.05).
        assert!((c.dual_success_rate - (1.0 - 184.0 / 671.0)).abs() < 0.05);
        // Same draws for every dual run: more coordination, less time per attempt.
        let c23 = single_vs_dual(PolicyKind::V2023, &base, 2000).expect("runs");
        let cb = single_vs_dual(PolicyKind::Baseline, &base, 2000).expect("runs");
        assert!(c.dual_s_per_attempt < c23.dual_s_per_attempt);
        assert!(c23.dual_s_per_attempt < cb.dual_s_per_attempt);
        assert_eq!(c.single_s_per_attempt, cb.single_s_per_attempt);
    }
}
