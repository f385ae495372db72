//! End-to-end tests of the in-process harvesting loop. All times are simulated (deterministic
//! for a seed); nothing here measures or asserts wall-clock time.

use super::calibration::pressure_for;
use super::detections::DetectionModel;
use super::records::FailureCause;
use super::report::HarvestSummary;
use super::runner::{EpisodeConfig, EpisodeOutcome, run_episode};
use super::timing::apply_timing;
use super::*;
use harvest_arm::node::ArmNodeConfig;
use harvest_safety::safety_monitor::Violation;
use harvest_sim::scenario::Scenario;
use harvest_vacuum::policy::PolicyKind;
use harvest_vacuum::pressure::PressureConfig;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

fn episode(
    scenario: &str,
    timing: TimingArg,
    policy: PolicyKind,
    arms: u8,
    seed: u64,
    noise: f64,
) -> EpisodeConfig {
    let mut scenario = Scenario::preset(scenario).expect("preset");
    let mut arm_node = ArmNodeConfig::default();
    let mut pressure = PressureConfig::default();
    apply_timing(&mut scenario, &mut arm_node, &mut pressure, timing);
    let pressure = pressure_for(&scenario.vacuum, pressure).expect("thresholds");
    let mut config = EpisodeConfig::new(scenario, policy, arms, seed);
    config.arm_node = arm_node;
    config.pressure = pressure;
    config.detection = DetectionModel {
        noise_scale: noise,
        ..DetectionModel::default()
    };
    config
}

fn summary(outcome: &EpisodeOutcome) -> HarvestSummary {
    HarvestSummary::of(&[outcome])
}

/// Fig. 12 from the full loop: `ideal` scenario, the paper's phase times, exact detections.
#[test]
fn fig_12_cycle_times_come_out_of_the_full_loop() {
    let run = |policy| {
        let outcome =
            run_episode(&episode("ideal", TimingArg::Fig12, policy, 2, 1, 0.0)).expect("episode");
        assert!(!outcome.truncated);
        summary(&outcome)
    };
    let baseline = run(PolicyKind::Baseline);
    let v2023 = run(PolicyKind::V2023);
    let v2024 = run(PolicyKind::V2024);
    for s in [&baseline, &v2023, &v2024] {
        // The calibrated phase times: M about 2 s, A + R about 0.5 s.
        let p = s.mean_phase;
        let movement = (p.approach_s.unwrap_or(0.0) + p.retract_s.unwrap_or(0.0)) / 2.0;
        assert!((movement - 2.0).abs() < 0.1, "movement {movement}");
        // Every apple the arms can reach is harvested on its first attempt.
        assert_eq!(s.apples_harvested, s.apples_attempted);
        assert_eq!(s.first_attempt_successes, s.apples_harvested);
        assert!(s.apples_harvested >= 14, "{s:?}");
        assert_eq!(s.attempts, s.apples_attempted);
    }
    let a_plus_r =
        v2024.mean_phase.attach_s.unwrap_or(0.0) + v2024.mean_phase.release_s.unwrap_or(0.0);
    assert!((a_plus_r - 0.5).abs() < 0.1, "A + R {a_plus_r}");
    let interval = |s: &HarvestSummary| s.release_interval_s.unwrap_or(f64::NAN);
    let steady = |s: &HarvestSummary| s.steady_release_interval_s.unwrap_or(f64::NAN);
    // Baseline: one apple per single-arm cycle, 2M + A + R = 4.5 s.
    assert!(
        (interval(&baseline) - 4.5).abs() < 0.15,
        "{}",
        interval(&baseline)
    );
    // 2023: A + M + R = 2.5 s while both arms work.
    assert!((steady(&v2023) - 2.5).abs() < 0.2, "{}", steady(&v2023));
    // 2024: half the single-arm cycle, at most 2.25 s, while both arms work.
    assert!(steady(&v2024) <= 2.25, "{}", steady(&v2024));
    assert!(steady(&v2024) < steady(&v2023) && steady(&v2023) < steady(&baseline));
    assert!(
        v2024.seconds_per_apple < v2023.seconds_per_apple
            && v2023.seconds_per_apple < baseline.seconds_per_apple
    );
    assert_eq!(v2024.safety_violations, 0);
    // The time budget accounts for the whole run of both arms.
    for s in [&baseline, &v2023, &v2024] {
        let b = s.time_budget;
        let total = b.startup_s + b.attempts_s + b.between_attempts_s + b.tail_s;
        assert!(
            (total - 2.0 * s.duration_s).abs() < 1e-6,
            "{b:?} vs {}",
            s.duration_s
        );
    }
    // 2024: the whole run exceeds the evenly spread floor only by start-up, gaps and tail.
    let b = v2024.time_budget;
    let floor = b.balanced_seconds_per_apple.unwrap_or(f64::NAN);
    let whole = v2024.seconds_per_apple.unwrap_or(f64::NAN);
    let excess = (b.startup_s + b.between_attempts_s + b.tail_s) / 2.0;
    assert!(
        (whole - floor - excess / f64::from(v2024.apples_harvested)).abs() < 1e-6,
        "{whole} {floor} {excess}"
    );
}

/// With the field's failure mix (`default` scenario), two arms need less time per attempt than
/// one (field: 5.97 s vs 8.29 s).
#[test]
fn dual_arm_attempts_are_faster_than_single_arm_ones_with_failures() {
    let run = |arms| {
        let outcomes: Vec<EpisodeOutcome> = (1..=3)
            .map(|seed| {
                run_episode(&episode(
                    "default",
                    TimingArg::Scenario,
                    PolicyKind::V2024,
                    arms,
                    seed,
                    1.0,
                ))
                .expect("episode")
            })
            .collect();
        HarvestSummary::of(&outcomes.iter().collect::<Vec<_>>())
    };
    let single = run(1);
    let dual = run(2);
    assert!(!single.failure_causes.is_empty() && !dual.failure_causes.is_empty());
    let (s, d) = (
        single.seconds_per_attempt.expect("attempts"),
        dual.seconds_per_attempt.expect("attempts"),
    );
    assert!(d < 0.85 * s, "single {s} s, dual {d} s per attempt");
    assert!(dual.apples_attempted > single.apples_attempted);
    assert_eq!(dual.safety_violations, 0);
}

/// The safety property: randomized short episodes with injected failures; the independent
/// monitor finds no violation under the 2024 policy.
#[test]
fn no_safety_violation_in_1000_randomized_episodes_under_the_2024_policy() {
    let mut rng = SmallRng::seed_from_u64(2024);
    let mut failures_seen = 0u32;
    let mut attempts = 0u32;
    let mut trace_events = 0u64;
    let mut violations: Vec<(u64, Violation)> = Vec::new();
    for k in 0..1000u64 {
        let preset = ["ideal", "default", "gala_vertical_wall", "fuji_ufo"][rng.random_range(0..4)];
        let timing = if rng.random_bool(0.5) {
            TimingArg::Fig12
        } else {
            TimingArg::Scenario
        };
        let mut config = episode(
            preset,
            timing,
            PolicyKind::V2024,
            2,
            k,
            rng.random_range(0.0..2.0),
        );
        let f = &mut config.scenario.failures;
        f.seal_failure = rng.random_range(0.0..0.6);
        f.holding_interference = rng.random_range(0.0..0.6);
        f.insufficient_detachment_force = rng.random_range(0.0..0.4);
        config.max_episode_s = rng.random_range(4.0..12.0);
        config.keep_events = false;
        let outcome = run_episode(&config).expect("episode");
        attempts += outcome.recorder.attempts.len() as u32;
        failures_seen += outcome
            .recorder
            .attempts
            .iter()
            .filter(|a| a.cause.is_some())
            .count() as u32;
        trace_events += outcome.trace_events;
        violations.extend(outcome.violations.iter().map(|v| (k, *v)));
    }
    println!(
        "1000 episodes: {attempts} attempts, {failures_seen} failed, {trace_events} trace events, \
         {} violations",
        violations.len()
    );
    assert!(
        failures_seen > 500,
        "failures were injected: {failures_seen}"
    );
    assert!(trace_events > 1_000_000);
    assert!(
        violations.is_empty(),
        "{:?}",
        &violations[..violations.len().min(5)]
    );
}

/// The monitor is not blind: the 2023 policy keeps a failed arm's valve open (no pressure
/// feedback), which the monitor reports.
#[test]
fn the_monitor_flags_the_2023_policy_keeping_a_failed_valve_open() {
    let mut config = episode("ideal", TimingArg::Fig12, PolicyKind::V2023, 2, 5, 0.0);
    config.scenario.failures.seal_failure = 1.0;
    config.max_episode_s = 20.0;
    let outcome = run_episode(&config).expect("episode");
    assert!(
        outcome
            .violations
            .iter()
            .any(|v| matches!(v, Violation::FailureNotClosed { .. }))
    );
    assert!(
        outcome
            .recorder
            .attempts
            .iter()
            .filter(|a| a.ended_s.is_some())
            .all(|a| a.cause == Some(FailureCause::Sealing)),
        "{:?}",
        outcome.recorder.attempts
    );
}

#[test]
fn emergency_stop_closes_the_valves_and_stops_the_arms_within_one_period() {
    for (k, at_s) in [0.8, 2.3024, 3.1, 6.0013].into_iter().enumerate() {
        let mut config = episode(
            "ideal",
            TimingArg::Scenario,
            PolicyKind::V2024,
            2,
            k as u64,
            0.0,
        );
        config.emergency_stop_at_s = Some(at_s);
        let outcome = run_episode(&config).expect("episode");
        let m = outcome.emergency_stop.expect("measured");
        let commanded = m.commanded_s.expect("commanded");
        assert!((0.0..0.005).contains(&commanded), "{m:?}");
        let travel = config.scenario.vacuum.valve_travel_time_s;
        let closed = m.valves_closed_s.expect("closed");
        assert!(closed <= travel + 0.01, "{m:?}");
        let stopped = m.arms_stopped_s.expect("stopped");
        assert!(stopped < 0.3, "{m:?}");
        assert!(outcome.violations.is_empty(), "{:?}", outcome.violations);
    }
}

#[test]
fn every_attempt_is_recorded_with_phases_and_a_cause_when_it_failed() {
    let mut config = episode("ideal", TimingArg::Scenario, PolicyKind::V2024, 2, 3, 1.0);
    config.scenario.failures.seal_failure = 0.3;
    config.scenario.failures.holding_interference = 0.3;
    let outcome = run_episode(&config).expect("episode");
    assert!(!outcome.truncated);
    let s = summary(&outcome);
    assert!(s.attempts > s.apples_harvested);
    for a in &outcome.recorder.attempts {
        assert!(a.ended_s.is_some(), "{a:?}");
        assert_eq!(a.harvested, a.cause.is_none(), "{a:?}");
        if a.started_s.is_some() {
            assert_eq!(a.phases.first().map(|p| p.phase.as_str()), Some("Approach"));
            let starts: Vec<f64> = a.phases.iter().map(|p| p.start_s).collect();
            assert!(starts.windows(2).all(|w| w[0] <= w[1]));
        }
    }
    // The per-apple view agrees with the world.
    let harvested = outcome.apples.iter().filter(|a| a.harvested).count() as u32;
    assert_eq!(harvested, s.apples_harvested);
    assert!(
        outcome
            .apples
            .iter()
            .all(|a| a.attempts >= 1 && a.attempts <= 4)
    );
    assert!(!outcome.recorder.events.is_empty());
}

#[test]
fn the_entry_point_checks_its_arguments_and_writes_json() {
    let bad = EvalHarvestArgs {
        episodes: 0,
        ..EvalHarvestArgs::default()
    };
    assert!(matches!(
        run_eval_harvest(&bad),
        Err(HarvestEvalError::InvalidArgument {
            arg: "--episodes",
            ..
        })
    ));
    let path = std::env::temp_dir().join(format!("harvest_eval_{}.json", std::process::id()));
    let args = EvalHarvestArgs {
        json: Some(path.clone()),
        detection_noise: 0.0,
        timing: TimingArg::Fig12,
        ..EvalHarvestArgs::default()
    };
    let report = run_eval_harvest(&args).expect("run");
    let text = std::fs::read_to_string(&path).expect("json written");
    let _ = std::fs::remove_file(&path);
    let value: serde_json::Value = serde_json::from_str(&text).expect("valid json");
    assert_eq!(
        value["summary"]["apples_harvested"].as_u64(),
        Some(u64::from(report.summary.apples_harvested))
    );
    assert!(report.render_text().contains("s/attempt"));
}

/// Prints the numbers of the report (not a check): Fig. 12 from the full loop, single vs dual
/// arm with failures, the emergency-stop reaction. Run with
/// `cargo test -p harvest-eval --release harvest::tests::report_numbers -- --ignored --nocapture`.
#[test]
#[ignore]
fn report_numbers() {
    let policies = [PolicyKind::Baseline, PolicyKind::V2023, PolicyKind::V2024];
    let run = |preset: &str, timing, policy, arms, seeds: std::ops::Range<u64>, noise| {
        let outcomes: Vec<EpisodeOutcome> = seeds
            .map(|seed| {
                run_episode(&episode(preset, timing, policy, arms, seed, noise)).expect("episode")
            })
            .collect();
        HarvestSummary::of(&outcomes.iter().collect::<Vec<_>>())
    };
    let show = |label: &str, s: &HarvestSummary| {
        let f = |v: Option<f64>| v.map_or_else(|| "-".to_owned(), |v| format!("{v:.2}"));
        let p = s.mean_phase;
        println!(
            "{label:<44} {:>3}/{:<3} harvested, {:>3} attempts | s/apple {:>6} s/attempt {:>5} \
             release {:>5} steady {:>5} | M {} A {} R {} | violations {}",
            s.apples_harvested,
            s.apples_attempted,
            s.attempts,
            f(s.seconds_per_apple),
            f(s.seconds_per_attempt),
            f(s.release_interval_s),
            f(s.steady_release_interval_s),
            f(p.approach_s.zip(p.retract_s).map(|(a, r)| (a + r) / 2.0)),
            f(p.attach_s),
            f(p.release_s),
            s.safety_violations
        );
    };
    for (timing, noise, seeds) in [
        (TimingArg::Fig12, 0.0, 1..2),
        (TimingArg::Fig12, 1.0, 1..11),
        (TimingArg::Scenario, 0.0, 1..2),
    ] {
        for policy in policies {
            let s = run("ideal", timing, policy, 2, seeds.clone(), noise);
            show(&format!("ideal {timing:?} noise {noise} {policy}"), &s);
        }
    }
    for preset in ["default", "gala_vertical_wall", "fuji_ufo"] {
        for (policy, arms) in [
            (PolicyKind::V2024, 1),
            (PolicyKind::Baseline, 2),
            (PolicyKind::V2023, 2),
            (PolicyKind::V2024, 2),
        ] {
            let s = run(preset, TimingArg::Scenario, policy, arms, 1..21, 1.0);
            show(&format!("{preset} {policy} {arms} arm(s), 20 seeds"), &s);
            if arms == 2 && policy == PolicyKind::V2024 {
                println!("    failure causes: {:?}", s.failure_causes);
            }
        }
    }
    for timing in [TimingArg::Scenario, TimingArg::Fig12] {
        let mut worst = [0.0f64; 3];
        for k in 0..200u64 {
            let mut config = episode("default", timing, PolicyKind::V2024, 2, k, 1.0);
            config.emergency_stop_at_s = Some(0.5 + 0.0371 * k as f64);
            let outcome = run_episode(&config).expect("episode");
            let m = outcome.emergency_stop.expect("measured");
            for (w, v) in worst
                .iter_mut()
                .zip([m.commanded_s, m.valves_closed_s, m.arms_stopped_s])
            {
                *w = w.max(v.unwrap_or(f64::INFINITY));
            }
        }
        println!(
            "emergency stop ({timing:?}), worst of 200: commands {:.4} s, valves closed {:.3} s, \
             arms stopped {:.3} s",
            worst[0], worst[1], worst[2]
        );
    }
}
