//! SIGINT/SIGTERM reach every loop through one mechanism (`harvest_ipc::termination`), even after
//! iceoryx2's own signal handling was touched. One test: the flag is process-wide and sticky.

use harvest_ipc::{Flow, RunEnd, Waiter, termination};
use iceoryx2::prelude::*;
use nix::sys::signal::{Signal, raise};
use std::time::Duration;

#[test]
fn sigterm_sets_the_flag_and_ends_the_waiter() {
    let waiter = Waiter::new().expect("waiter installs the handler");
    assert!(!termination::requested());

    // Something in the process uses iceoryx2's signal handling (a wait set that handles
    // termination requests itself): our handler must stay in place.
    let iceoryx2_waitset = WaitSetBuilder::new()
        .signal_handling_mode(SignalHandlingMode::HandleTerminationRequests)
        .create::<harvest_ipc::Ipc>()
        .expect("iceoryx2 wait set");
    let _guard = iceoryx2_waitset
        .attach_interval(Duration::from_millis(1))
        .expect("interval");
    iceoryx2_waitset
        .wait_and_process_once(|_| CallbackProgression::Continue)
        .expect("one wait of the iceoryx2 wait set");

    // A thread-directed signal is handled before `raise` returns.
    raise(Signal::SIGTERM).expect("raise SIGTERM");
    assert!(termination::requested(), "our handler did not see SIGTERM");

    // The waiter ends on the flag, without running its callback.
    let _interval = waiter
        .attach_interval(Duration::from_secs(3600))
        .expect("interval");
    let end = waiter
        .run(|_| -> Result<Flow, std::convert::Infallible> {
            panic!("the callback must not run after SIGTERM")
        })
        .expect("run");
    assert_eq!(end, RunEnd::Signal);
}
