//! The harness every device conformance suite shares (valve board, RGB-D camera, arm servos,
//! platform): the failure type naming the check and what was observed, the report of a passing
//! run, helpers that turn device results into check failures, a bounded poll loop, the runner
//! that gives each check a fresh device, and a watchdog for tests.
//!
//! A suite is a list of named checks `fn(&Config, &mut Device) -> Result<(), ConformanceError>`
//! handed to [`run_checks`]. Waits are bounded by the suite's timeouts (liveness bounds far
//! above the device's nominal timing, never timing assertions).

use crate::error_kind::{DeviceError, ErrorKind};
use std::sync::mpsc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// What a passing run checked.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConformanceReport {
    /// Names of the checks that passed, in order.
    pub checks_passed: Vec<&'static str>,
}

/// A conformance check that failed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ConformanceError {
    /// A call that must succeed returned an error.
    #[error("check `{check}`: {call} failed with kind {kind:?}: {message}")]
    CallFailed {
        /// The check.
        check: &'static str,
        /// The call, e.g. `set_valve(3, open)`.
        call: String,
        /// The error's kind.
        kind: ErrorKind,
        /// The error's message.
        message: String,
    },
    /// A call that must fail succeeded, or failed with the wrong kind.
    #[error("check `{check}`: {call} should fail with kind {expected:?}, got {got}")]
    WrongOutcome {
        /// The check.
        check: &'static str,
        /// The call.
        call: String,
        /// The kind required.
        expected: ErrorKind,
        /// What happened instead.
        got: String,
    },
    /// The device's observable state broke a rule.
    #[error("check `{check}`: {detail}")]
    Violated {
        /// The check.
        check: &'static str,
        /// What was observed.
        detail: String,
    },
}

/// Turns a device error into [`ConformanceError::CallFailed`]; `call` names the call (built
/// only on failure).
pub fn call<T, E: DeviceError>(
    check: &'static str,
    call: impl FnOnce() -> String,
    result: Result<T, E>,
) -> Result<T, ConformanceError> {
    result.map_err(|e| ConformanceError::CallFailed {
        check,
        call: call(),
        kind: e.kind(),
        message: e.to_string(),
    })
}

/// A [`ConformanceError::Violated`].
pub fn violated(check: &'static str, detail: String) -> ConformanceError {
    ConformanceError::Violated { check, detail }
}

/// Requires `result` to be an error of kind `expected` with a non-empty message, and returns
/// that error; anything else is [`ConformanceError::WrongOutcome`].
pub fn expect_refusal<T: std::fmt::Debug, E: DeviceError>(
    check: &'static str,
    call: impl FnOnce() -> String,
    expected: ErrorKind,
    result: Result<T, E>,
) -> Result<E, ConformanceError> {
    let got = match result {
        Err(error) if error.kind() == expected && !error.to_string().trim().is_empty() => {
            return Ok(error);
        }
        Err(error) if error.kind() == expected => "an error with an empty message".to_owned(),
        Err(error) => format!("{:?}: {error}", error.kind()),
        Ok(value) => format!("Ok({value:?})"),
    };
    Err(ConformanceError::WrongOutcome {
        check,
        call: call(),
        expected,
        got,
    })
}

/// How long to keep polling, and how often.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PollBounds {
    /// Longest wait before the check fails (a liveness bound, not a timing requirement).
    pub timeout: Duration,
    /// Pause between two polls.
    pub interval: Duration,
}

/// One poll's outcome.
#[derive(Debug, Clone, PartialEq)]
pub enum Probe<T> {
    /// The awaited condition holds.
    Done(T),
    /// Not yet; the text describes the state observed (reported if the wait times out).
    Waiting(String),
}

/// Calls `probe` every `bounds.interval` until it returns [`Probe::Done`] or an error, or
/// `bounds.timeout` passes (then the check fails naming `what` and the last observed state).
pub fn poll_until<T>(
    check: &'static str,
    bounds: PollBounds,
    what: &str,
    mut probe: impl FnMut() -> Result<Probe<T>, ConformanceError>,
) -> Result<T, ConformanceError> {
    let deadline = Instant::now() + bounds.timeout;
    loop {
        let last = match probe()? {
            Probe::Done(value) => return Ok(value),
            Probe::Waiting(last) => last,
        };
        if Instant::now() >= deadline {
            return Err(violated(
                check,
                format!(
                    "{what} not reached within {} ms; last observed: {last}",
                    bounds.timeout.as_millis()
                ),
            ));
        }
        std::thread::sleep(bounds.interval);
    }
}

/// Reads the device `samples` times, `bounds.interval` apart, after a `first` reading: every
/// reading's stamp (`stamp_ns`) must not be earlier than the one before and the reading must
/// pass `valid` (its error is the failure's detail). Then waits, within `bounds.timeout`, for a
/// stamp later than `first`'s (a live device keeps sampling while nothing moves); `newer` names
/// that reading in the failure.
pub fn stamps_advance<T>(
    check: &'static str,
    bounds: PollBounds,
    samples: usize,
    newer: &str,
    mut read: impl FnMut() -> Result<T, ConformanceError>,
    stamp_ns: impl Fn(&T) -> u64,
    valid: impl Fn(&T) -> Result<(), String>,
) -> Result<(), ConformanceError> {
    let first_ns = stamp_ns(&read()?);
    let mut last_ns = first_ns;
    for _ in 0..samples {
        std::thread::sleep(bounds.interval);
        let now = read()?;
        let now_ns = stamp_ns(&now);
        if now_ns < last_ns {
            return Err(violated(
                check,
                format!("stamp went back from {last_ns} to {now_ns} ns"),
            ));
        }
        valid(&now).map_err(|detail| violated(check, detail))?;
        last_ns = now_ns;
    }
    poll_until(check, bounds, newer, || {
        let now_ns = stamp_ns(&read()?);
        Ok(if now_ns > first_ns {
            Probe::Done(())
        } else {
            Probe::Waiting(format!("stamp still {now_ns} ns"))
        })
    })
}

/// One named check of a suite over config `C` and device `D`.
pub type Check<C, D> = (&'static str, fn(&C, &mut D) -> Result<(), ConformanceError>);

/// Runs `checks` in order, each on a fresh device from `make`, then `after_each` on the same
/// device (e.g. "no faults reported"); stops at the first failure.
pub fn run_checks<C, D>(
    suite: &'static str,
    config: &C,
    checks: &[Check<C, D>],
    mut make: impl FnMut() -> D,
    mut after_each: impl FnMut(&'static str, &mut D) -> Result<(), ConformanceError>,
) -> Result<ConformanceReport, ConformanceError> {
    let mut report = ConformanceReport {
        checks_passed: Vec::with_capacity(checks.len()),
    };
    for &(name, check) in checks {
        let mut device = make();
        check(config, &mut device)?;
        after_each(name, &mut device)?;
        tracing::debug!(suite, check = name, "conformance check passed");
        report.checks_passed.push(name);
    }
    Ok(report)
}

/// Aborts the whole test process if a test runs longer than its limit, so a hung device
/// exchange fails CI instead of stalling it. Test support; dropping the guard disarms it.
#[derive(Debug)]
pub struct TestWatchdog {
    disarm: Option<mpsc::Sender<()>>,
    thread: Option<JoinHandle<()>>,
}

impl TestWatchdog {
    /// Arm a watchdog named `test` that aborts the process after `limit`.
    pub fn arm(test: &str, limit: Duration) -> TestWatchdog {
        let (disarm, disarmed) = mpsc::channel::<()>();
        let name = test.to_owned();
        let thread = std::thread::Builder::new()
            .name(format!("watchdog-{name}"))
            .spawn(move || {
                if let Err(mpsc::RecvTimeoutError::Timeout) = disarmed.recv_timeout(limit) {
                    tracing::error!(test = %name, limit_s = limit.as_secs_f64(), "test watchdog fired");
                    eprintln!(
                        "watchdog: test `{name}` still running after {:.1} s; aborting",
                        limit.as_secs_f64()
                    );
                    std::process::abort();
                }
            })
            .ok();
        TestWatchdog {
            disarm: Some(disarm),
            thread,
        }
    }
}

impl Drop for TestWatchdog {
    fn drop(&mut self) {
        drop(self.disarm.take());
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, thiserror::Error)]
    #[error("refused {0}")]
    struct Refused(u32);

    impl DeviceError for Refused {
        fn kind(&self) -> ErrorKind {
            ErrorKind::InvalidRequest
        }
    }

    #[test]
    fn expect_refusal_accepts_only_the_expected_kind() {
        let refused: Result<(), Refused> = Err(Refused(3));
        assert!(expect_refusal("t", || "c".into(), ErrorKind::InvalidRequest, refused).is_ok());
        let accepted: Result<u8, Refused> = Ok(7);
        let error = expect_refusal("t", || "c".into(), ErrorKind::InvalidRequest, accepted)
            .expect_err("Ok must be a wrong outcome");
        assert_eq!(
            error,
            ConformanceError::WrongOutcome {
                check: "t",
                call: "c".into(),
                expected: ErrorKind::InvalidRequest,
                got: "Ok(7)".into(),
            }
        );
        let wrong_kind: Result<(), Refused> = Err(Refused(1));
        assert!(expect_refusal("t", || "c".into(), ErrorKind::Timeout, wrong_kind).is_err());
    }

    #[test]
    fn poll_until_returns_the_first_done_and_times_out_with_the_last_state() {
        let bounds = PollBounds {
            timeout: Duration::from_secs(5),
            interval: Duration::from_millis(1),
        };
        let mut polls = 0;
        let found = poll_until("t", bounds, "three polls", || {
            polls += 1;
            Ok(if polls == 3 {
                Probe::Done(polls)
            } else {
                Probe::Waiting(format!("poll {polls}"))
            })
        });
        assert_eq!(found, Ok(3));
        let never = poll_until::<()>(
            "t",
            PollBounds {
                timeout: Duration::ZERO,
                interval: Duration::ZERO,
            },
            "never",
            || Ok(Probe::Waiting("still 0".into())),
        );
        let Err(ConformanceError::Violated { detail, .. }) = never else {
            panic!("expected a violation, got {never:?}");
        };
        assert!(detail.contains("still 0"), "{detail}");
    }

    #[test]
    fn stamps_advance_refuses_a_stamp_going_back_an_invalid_reading_and_a_frozen_clock() {
        let bounds = PollBounds {
            timeout: Duration::ZERO,
            interval: Duration::ZERO,
        };
        let run = |stamps: Vec<u64>| {
            let mut stamps = stamps.into_iter();
            stamps_advance(
                "t",
                bounds,
                3,
                "a newer stamp",
                || Ok(stamps.next().unwrap_or(0)),
                |&stamp| stamp,
                |&stamp| {
                    if stamp == 99 {
                        Err("stamp 99 is invalid".to_owned())
                    } else {
                        Ok(())
                    }
                },
            )
        };
        assert_eq!(run(vec![1, 1, 2, 3, 4]), Ok(()));
        // Equal stamps are allowed while sampling, but a newer one must come.
        assert_eq!(run(vec![5, 5, 5, 6, 7]), Ok(()));
        let Err(ConformanceError::Violated { detail, .. }) = run(vec![1, 3, 2, 4, 5]) else {
            panic!("a stamp going back must fail");
        };
        assert!(detail.contains("from 3 to 2"), "{detail}");
        let Err(ConformanceError::Violated { detail, .. }) = run(vec![1, 2, 99, 100, 101]) else {
            panic!("an invalid reading must fail");
        };
        assert_eq!(detail, "stamp 99 is invalid");
        let Err(ConformanceError::Violated { detail, .. }) = run(vec![7, 7, 7, 7, 7]) else {
            panic!("a frozen clock must fail");
        };
        assert!(detail.contains("a newer stamp"), "{detail}");
    }

    #[test]
    fn run_checks_gives_each_check_a_fresh_device_and_stops_at_the_first_failure() {
        fn passes(_: &(), device: &mut Vec<u8>) -> Result<(), ConformanceError> {
            device.push(1);
            Ok(())
        }
        fn fails(_: &(), _: &mut Vec<u8>) -> Result<(), ConformanceError> {
            Err(violated("fails", "always".into()))
        }
        let mut made = 0;
        let checks: [Check<(), Vec<u8>>; 3] = [("a", passes), ("b", passes), ("c", fails)];
        let result = run_checks(
            "demo",
            &(),
            &checks,
            || {
                made += 1;
                Vec::new()
            },
            |_, device| {
                if device.len() == 1 {
                    Ok(())
                } else {
                    Err(violated("after", format!("device reused: {device:?}")))
                }
            },
        );
        assert_eq!(result, Err(violated("fails", "always".into())));
        assert_eq!(made, 3);
        let passing = run_checks("demo", &(), &checks[..2], Vec::new, |_, _| Ok(()));
        assert_eq!(
            passing,
            Ok(ConformanceReport {
                checks_passed: vec!["a", "b"],
            })
        );
    }
}
