//! Measures how regularly the simulated servo controllers serve their encoder feedback in a
//! running stack: the distribution of the intervals between consecutive `hw/armN/encoders`
//! publish stamps (nominal 5 ms, the 200 Hz servo loop), beside the arm control loops' own
//! periods (`armN/state` publish stamps). Reports numbers; asserts nothing.
//!
//! ```text
//! HARVEST_DOMAIN=mine harvest up &                      # the stack to measure
//! HARVEST_DOMAIN=mine cargo run --release -p harvest-sim --example encoder_period -- 20
//! ```
//! The argument is the collection time in seconds (default 20); collection starts once the
//! first encoder sample arrived.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

use harvest_ipc::catalogue::{ARM_STATE, HW_ARM_ENCODERS};
use harvest_ipc::period_stats::PeriodStats;
use harvest_ipc::{Context, Domain, Flow, Payload, Subscriber, Waiter};
use std::time::{Duration, Instant};

/// How often the probe drains its subscribers (well inside their 256-sample buffers).
const DRAIN_PERIOD: Duration = Duration::from_millis(20);
/// Nominal period of both the servo loop and the arm loop, ns (200 Hz).
const NOMINAL_NS: u64 = 5_000_000;
/// Longest wait for the first encoder sample.
const STARTUP_TIMEOUT: Duration = Duration::from_secs(60);

/// One probed channel and the intervals between its publish stamps.
struct Probe<T: Payload> {
    name: &'static str,
    subscriber: Subscriber<T>,
    stats: PeriodStats,
}

impl<T: Payload> Probe<T> {
    /// Takes every buffered sample; records its publish stamp when `record`.
    fn drain(&mut self, record: bool) -> Result<u64, Box<dyn std::error::Error>> {
        let mut samples = 0;
        while let Some(sample) = self.subscriber.receive()? {
            samples += 1;
            if record {
                self.stats.tick(sample.header().publish_ns);
            }
        }
        Ok(samples)
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let seconds: f64 = std::env::args()
        .nth(1)
        .map(|arg| arg.parse())
        .transpose()?
        .unwrap_or(20.0);
    let domain = Domain::from_flag_or_env(None)?;
    let context = Context::new(&domain, "encoder-period-probe")?;
    let mut encoders = Vec::new();
    let mut states = Vec::new();
    for arm in 0..2 {
        encoders.push(Probe {
            name: HW_ARM_ENCODERS[arm].spec.topic,
            subscriber: context.subscriber_with_buffer(HW_ARM_ENCODERS[arm], 256)?,
            stats: PeriodStats::new(NOMINAL_NS)?,
        });
        states.push(Probe {
            name: ARM_STATE[arm].spec.topic,
            subscriber: context.subscriber_with_buffer(ARM_STATE[arm], 256)?,
            stats: PeriodStats::new(NOMINAL_NS)?,
        });
    }
    let waiter = Waiter::new()?;
    let drain_tick = waiter.attach_interval(DRAIN_PERIOD)?;
    let started = Instant::now();
    let mut collecting_since: Option<Instant> = None;
    waiter
        .run(|attachment| -> Result<Flow, Box<dyn std::error::Error>> {
            if !attachment.has_event_from(&drain_tick) {
                return Ok(Flow::Continue);
            }
            let record = collecting_since.is_some();
            let mut arrived = 0;
            for probe in &mut encoders {
                arrived += probe.drain(record)?;
            }
            for probe in &mut states {
                probe.drain(record)?;
            }
            match collecting_since {
                None if arrived > 0 => collecting_since = Some(Instant::now()),
                None if started.elapsed() > STARTUP_TIMEOUT => {
                    return Err(format!(
                        "no encoder feedback in domain {:?} within {STARTUP_TIMEOUT:?}",
                        domain.name()
                    )
                    .into());
                }
                Some(since) if since.elapsed().as_secs_f64() >= seconds => {
                    return Ok(Flow::Stop);
                }
                _ => {}
            }
            Ok(Flow::Continue)
        })
        .map_err(|error| match error {
            harvest_ipc::RunError::Wait(error) => Box::new(error),
            harvest_ipc::RunError::Callback(error) => error,
        })?;
    println!(
        "publish-stamp intervals over {seconds} s (domain {}):",
        domain.name()
    );
    let summaries = encoders
        .iter()
        .map(|probe| (probe.name, probe.stats.summary()))
        .chain(
            states
                .iter()
                .map(|probe| (probe.name, probe.stats.summary())),
        );
    for (name, summary) in summaries {
        println!("  {name:<18} {summary}");
    }
    Ok(())
}
