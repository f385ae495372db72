//! Randomized property test: thousands of seeded episodes of the cycle model with injected
//! failures, each trace judged by the independent safety monitor.
//!
//! The 2024 policy must produce no violation and never deadlock; the 2023 and baseline
//! policies, which do not react to pressure feedback, must be caught leaving a failed valve
//! open; and a test-only policy that grants everything must be caught opening two unsealed
//! valves (so every vacuum rule of the monitor is shown to fire).

use crate::cycle_model::{CycleEpisode, DetectionTimes, FailureRates, PhaseTimes, run_episode};
use harvest_robot_model::ArmId;
use harvest_safety::safety_monitor::{MonitorConfig, Violation, check_trace};
use harvest_vacuum::policy::{
    Decision, PairStatus, PolicyKind, Request, VacuumPolicy, ValveOrder, new_policy,
};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

const MS: u64 = 1_000_000;
const EPISODES: u64 = 3000;

/// A random valid episode: phase times, latencies, failure rates, jitter and counts.
fn random_episode(rng: &mut SmallRng, seed: u64) -> CycleEpisode {
    let attach_ns = rng.random_range(100..600) * MS;
    let attach_timeout_ns = rng.random_range(80..700) * MS;
    let seal_ns = rng.random_range(5..attach_ns.min(attach_timeout_ns) / MS) * MS;
    CycleEpisode {
        phase_times: PhaseTimes {
            approach_ns: rng.random_range(300..3000) * MS,
            attach_ns,
            retract_ns: rng.random_range(300..3000) * MS,
            release_ns: rng.random_range(50..600) * MS,
        },
        detection: DetectionTimes {
            seal_ns,
            attach_timeout_ns,
            drop_ns: rng.random_range(5..60) * MS,
        },
        failures: FailureRates {
            no_seal: rng.random_range(0.0..0.5),
            detach_loss: rng.random_range(0.0..0.2),
            holding_loss: rng.random_range(0.0..0.2),
        },
        attempts_per_arm: [rng.random_range(0..8), rng.random_range(0..8)],
        movement_jitter: rng.random_range(0.0..0.8),
        seed,
        record_trace: true,
    }
}

/// Violations of each kind over all episodes: [opened beside unsealed, both open unsealed,
/// failure not closed, other].
fn violation_counts(policy: &dyn VacuumPolicy) -> [usize; 4] {
    let mut rng = SmallRng::seed_from_u64(2024);
    let mut counts = [0; 4];
    for index in 0..EPISODES {
        let episode = random_episode(&mut rng, index);
        let result = match run_episode(policy, &episode) {
            Ok(r) => r,
            Err(e) => panic!("episode {index} {episode:?}: {e}"),
        };
        assert_eq!(
            result.attempts,
            episode.attempts_per_arm.iter().sum::<u32>(),
            "episode {index}: every attempt is made"
        );
        let violations =
            check_trace(&result.trace, MonitorConfig::default()).expect("model emits in order");
        for v in violations {
            counts[match v {
                Violation::OpenedBesideUnsealed { .. } => 0,
                Violation::BothOpenUnsealed { .. } => 1,
                Violation::FailureNotClosed { .. } => 2,
                _ => 3,
            }] += 1;
        }
    }
    counts
}

#[test]
fn policy_2024_has_no_violation_in_thousands_of_random_episodes() {
    let policy = new_policy(PolicyKind::V2024);
    assert_eq!(violation_counts(policy.as_ref()), [0, 0, 0, 0]);
}

#[test]
fn baseline_and_2023_are_caught_leaving_failed_valves_open() {
    for kind in [PolicyKind::Baseline, PolicyKind::V2023] {
        let counts = violation_counts(new_policy(kind).as_ref());
        // They never open two valves at once (sequential / exclusive vacuum)...
        assert_eq!(counts[0] + counts[1], 0, "{kind}: {counts:?}");
        // ...but do not react to failures.
        assert!(counts[2] > 100, "{kind}: {counts:?}");
        assert_eq!(counts[3], 0);
    }
}

/// Grants every request the arm's own workflow allows and only ever closes for the release:
/// no coordination of the vacuum at all.
struct GrantEverything;

impl VacuumPolicy for GrantEverything {
    fn kind(&self) -> PolicyKind {
        PolicyKind::Baseline
    }

    fn decide(&self, arm: ArmId, request: Request, arms: &PairStatus) -> Decision {
        match harvest_vacuum::policy::own_preconditions(arms.arm(arm), request) {
            Ok(()) => Decision::Grant,
            Err(reason) => Decision::Refuse(reason),
        }
    }

    fn supervise(&self, arms: &PairStatus) -> [ValveOrder; 2] {
        ArmId::ALL.map(|arm| harvest_vacuum::policy::workflow_close(arms.arm(arm)))
    }
}

#[test]
fn uncoordinated_policy_is_caught_opening_two_unsealed_valves() {
    let counts = violation_counts(&GrantEverything);
    assert!(counts[0] > 100, "{counts:?}");
    assert!(counts[1] > 100, "{counts:?}");
    assert!(counts[2] > 100, "{counts:?}");
}
