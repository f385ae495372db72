//! The soak's seeded schedule: when to kill which process, which operator scenario to run and
//! which bad input to feed. Made up front from `--seed`, so a run can be repeated.

use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use serde::Serialize;
use std::time::Duration;

/// One thing the soak does at a time after the stack's start.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Action {
    /// SIGKILL the process of this launch name.
    Kill { process: String },
    /// `harvest ctl <args>`; `expect` is what a sound stack answers.
    Ctl { args: Vec<String>, expect: Expect },
    /// A bad input.
    BadInput { input: BadInput },
}

/// What the soak expects of a command.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Expect {
    /// An answer, accepted or refused (the mode may forbid it at that moment).
    Answer,
    /// A refusal (exit 1): bad token, values past the limits.
    Refused,
}

/// The bad inputs the soak feeds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BadInput {
    /// `harvest ctl --token <random> pause`.
    WrongToken,
    /// `harvest ctl jog --arm 1 --joint d --delta 5` (5 m, past the 0.1 m step).
    JogPastLimits,
    /// Random bytes in every field of an `operator/command` message.
    GarbageOperatorCommand,
    /// An `operator/command` with the real token but an unknown command code and a NaN value.
    UnknownCommandCode,
    /// Random bytes in a `harvest/events` message, its kind an unknown code.
    GarbageHarvestEvent,
    /// Random bytes in a `system/health` heartbeat.
    GarbageHeartbeat,
    /// A heartbeat named `arm1` with a pid that is not arm1's, state degraded.
    SpoofedHeartbeat,
}

const BAD_INPUTS: [BadInput; 7] = [
    BadInput::WrongToken,
    BadInput::JogPastLimits,
    BadInput::GarbageOperatorCommand,
    BadInput::UnknownCommandCode,
    BadInput::GarbageHarvestEvent,
    BadInput::GarbageHeartbeat,
    BadInput::SpoofedHeartbeat,
];

/// An action and when, from the stack's start.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Timed {
    #[serde(rename = "at_ms", serialize_with = "millis")]
    pub at: Duration,
    pub action: Action,
}

fn millis<S: serde::Serializer>(value: &Duration, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_u64(value.as_millis() as u64)
}

/// What the schedule is made from.
#[derive(Debug, Clone)]
pub struct ScheduleSpec {
    pub seed: u64,
    pub duration: Duration,
    pub warmup: Duration,
    pub kill_every: Duration,
    pub max_kills: Option<u32>,
    pub ctl_every: Duration,
    pub bad_input_every: Duration,
    /// Launch names of the processes that may be killed.
    pub processes: Vec<String>,
}

/// How long before the end nothing new starts (the last restart settles before the stop).
const QUIET_END: Duration = Duration::from_secs(10);

/// The whole schedule, in time order.
pub fn make_schedule(spec: &ScheduleSpec) -> Vec<Timed> {
    let mut rng = SmallRng::seed_from_u64(spec.seed);
    let end = spec.duration.saturating_sub(QUIET_END).max(spec.warmup);
    let mut timed = Vec::new();
    // Kills.
    let mut at = spec.warmup;
    let mut kills = 0u32;
    loop {
        at += jitter(&mut rng, spec.kill_every);
        if at >= end || spec.max_kills.is_some_and(|max| kills >= max) || spec.processes.is_empty()
        {
            break;
        }
        let process = spec.processes[rng.random_range(0..spec.processes.len())].clone();
        timed.push(Timed {
            at,
            action: Action::Kill { process },
        });
        kills += 1;
    }
    // Operator scenarios, one after another.
    let mut at = spec.warmup;
    loop {
        at += jitter(&mut rng, spec.ctl_every);
        let steps = scenario(rng.random_range(0..5u8), &mut rng);
        let last = at + steps.last().map_or(Duration::ZERO, |(after, _)| *after);
        if last >= end {
            break;
        }
        for (after, args) in steps {
            timed.push(Timed {
                at: at + after,
                action: Action::Ctl {
                    args: args.iter().map(|s| (*s).to_owned()).collect(),
                    expect: Expect::Answer,
                },
            });
        }
        at = last;
    }
    // Bad inputs.
    let mut at = spec.warmup;
    loop {
        at += jitter(&mut rng, spec.bad_input_every);
        if at >= end {
            break;
        }
        let input = BAD_INPUTS[rng.random_range(0..BAD_INPUTS.len())];
        timed.push(Timed {
            at,
            action: Action::BadInput { input },
        });
    }
    timed.sort_by_key(|t| t.at);
    timed
}

/// Uniform in 0.5x-1.5x of `mean`.
fn jitter(rng: &mut SmallRng, mean: Duration) -> Duration {
    mean.mul_f64(rng.random_range(0.5..1.5))
}

/// One operator scenario: (offset from its start, ctl arguments) per step.
fn scenario(which: u8, rng: &mut SmallRng) -> Vec<(Duration, Vec<&'static str>)> {
    let s = Duration::from_secs;
    let hold = s(rng.random_range(4..12));
    match which {
        0 => vec![(s(0), vec!["status"])],
        1 => vec![(s(0), vec!["pause"]), (hold, vec!["resume"])],
        2 => vec![
            (s(0), vec!["stop"]),
            (s(3), vec!["home"]),
            (s(3) + hold, vec!["start"]),
        ],
        3 => vec![
            (s(0), vec!["estop"]),
            (hold, vec!["release"]),
            (hold + s(2), vec!["start"]),
        ],
        _ => vec![
            (s(0), vec!["arm", "2", "disable"]),
            (hold, vec!["arm", "2", "enable"]),
        ],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> ScheduleSpec {
        ScheduleSpec {
            seed: 7,
            duration: Duration::from_secs(600),
            warmup: Duration::from_secs(10),
            kill_every: Duration::from_secs(60),
            max_kills: None,
            ctl_every: Duration::from_secs(30),
            bad_input_every: Duration::from_secs(20),
            processes: vec!["sim".to_owned(), "arm1".to_owned(), "recorder".to_owned()],
        }
    }

    #[test]
    fn the_schedule_is_seeded_sorted_and_inside_the_run() {
        let schedule = make_schedule(&spec());
        assert_eq!(schedule, make_schedule(&spec()));
        assert_ne!(schedule, make_schedule(&ScheduleSpec { seed: 8, ..spec() }));
        assert!(schedule.windows(2).all(|w| w[0].at <= w[1].at));
        assert!(
            schedule
                .iter()
                .all(|t| t.at > Duration::from_secs(10) && t.at < Duration::from_secs(590))
        );
        let kills = schedule
            .iter()
            .filter(|t| matches!(t.action, Action::Kill { .. }))
            .count();
        assert!((4..=19).contains(&kills), "{kills} kills");
        assert!(
            schedule
                .iter()
                .any(|t| matches!(t.action, Action::Ctl { .. }))
        );
        assert!(
            schedule
                .iter()
                .any(|t| matches!(t.action, Action::BadInput { .. }))
        );
    }

    #[test]
    fn max_kills_caps_the_kills() {
        let schedule = make_schedule(&ScheduleSpec {
            max_kills: Some(1),
            ..spec()
        });
        let kills = schedule
            .iter()
            .filter(|t| matches!(t.action, Action::Kill { .. }))
            .count();
        assert_eq!(kills, 1);
    }
}
