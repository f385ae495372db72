//! Waiting for a stream to settle before a benchmark measures it.

use harvest_ipc::error::ReceiveError;
use harvest_ipc::{Payload, Subscriber};
use std::time::{Duration, Instant};

/// Takes samples from `subscriber` until `count` have arrived (true) or `limit` has passed
/// (false); woken by the channel's events, never polling faster than each 100 ms wait.
pub fn settled<T: Payload>(
    subscriber: &Subscriber<T>,
    count: usize,
    limit: Duration,
) -> Result<bool, ReceiveError> {
    let deadline = Instant::now() + limit;
    let mut seen = 0;
    while seen < count {
        if Instant::now() > deadline {
            return Ok(false);
        }
        while subscriber.receive()?.is_some() {
            seen += 1;
        }
        let _ = subscriber
            .listener()
            .timed_wait(|_| {}, Duration::from_millis(100));
    }
    Ok(true)
}
