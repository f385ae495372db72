//! What the control loop and the transport calls of a 200 Hz process allocate per tick once
//! running: the loop itself (timer wait, clock, histogram), `receive`/`receive_latest` over real
//! iceoryx2 shared memory and the heartbeat's period summary allocate nothing; each sample sent
//! (`publish`/`publish_with`, the heartbeat's `report_control_loop`) allocates exactly one small
//! block, inside iceoryx2 0.10: `Publisher::loan_uninit` puts the sample's shared state in an
//! `Rc` (`iceoryx2/src/sample_mut_uninit.rs`, `ChunkMutSharedState::new`), freed when the sample
//! is sent. Same size every time, so glibc serves it from the thread's cache (no lock, no system
//! call) and, with the memory locked, without a page fault. Counted by `allocation_counter` on the thread that runs the loop, from the end of the warm-up to the
//! end of the loop. (What the arm and vacuum nodes do in a tick is counted in their own crates.)

use harvest_ipc::allocation_counter::{self, CountingAllocator};
use harvest_ipc::catalogue::{ARM_STATE, HARVEST_EVENTS};
use harvest_ipc::control_loop::{Wake, run_control_loop};
use harvest_ipc::payloads::{ArmState, HarvestEvent, HarvestEventKind, HarvestEventSource};
use harvest_ipc::{Context, FixedString, Flow, HealthReporter, Payload, ScratchDomain};

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

#[derive(Debug, thiserror::Error)]
enum LoopError {
    #[error(transparent)]
    Period(#[from] harvest_ipc::period_stats::PeriodStatsError),
    #[error(transparent)]
    Ipc(#[from] harvest_ipc::error::IpcError),
}
harvest_ipc::from_ipc_errors!(LoopError);

#[test]
fn a_running_control_loop_allocates_only_iceoryx2s_block_per_sample_sent() {
    const PERIOD_NS: u64 = 2_000_000;
    const WARM_UP_TICKS: u64 = 20;
    // 0.8 s at 2 ms: a heartbeat (every 0.5 s) falls inside the counted ticks.
    const TICKS: u64 = 400;
    let domain = ScratchDomain::new("loopalloc");
    let context = Context::new(&domain, "loop-alloc-test").expect("context");
    let mut state_out = context.publisher(ARM_STATE[0]).expect("publisher");
    let state_in = context.subscriber(ARM_STATE[0]).expect("subscriber");
    let mut events_out = context.publisher(HARVEST_EVENTS).expect("publisher");
    let events_in = context.subscriber(HARVEST_EVENTS).expect("subscriber");
    let mut health = HealthReporter::new(&context).expect("health");
    let mut ticks = 0u64;
    let mut received = 0u64;
    let mut heartbeats_counted = 0u64;
    let mut samples_sent_counted = 0u64;
    let mut allocations = 0u64;
    let summary = run_control_loop(PERIOD_NS, |wake| -> Result<Flow, LoopError> {
        match wake {
            Wake::Tick { now_ns } => {
                ticks += 1;
                if ticks == WARM_UP_TICKS {
                    allocation_counter::start();
                }
                state_out.publish_with(now_ns, |state: &mut ArmState| {
                    state.arm_id = 1;
                    state.control_period_ns = PERIOD_NS;
                })?;
                let mut event = HarvestEvent::new(
                    now_ns,
                    HarvestEventSource::Arm1,
                    HarvestEventKind::PhaseChanged,
                    1,
                    7,
                );
                event.reason = FixedString::new("Idle -> Approach");
                events_out.publish(&event)?;
                if allocation_counter::is_counting() {
                    samples_sent_counted += 2;
                }
                if let Some(state) = state_in.receive_latest()? {
                    received += u64::from(state.header().msg_seq > 0);
                }
                while let Some(event) = events_in.receive()? {
                    received += u64::from(event.apple_id == 7);
                }
            }
            Wake::Heartbeat { period } => {
                if allocation_counter::is_counting() {
                    heartbeats_counted += 1;
                    samples_sent_counted += 1;
                }
                health.report_control_loop(
                    harvest_ipc::payloads::ProcessRunState::Running,
                    ticks,
                    &period,
                )?;
            }
        }
        Ok(if ticks >= WARM_UP_TICKS + TICKS {
            allocations = allocation_counter::stop();
            Flow::Stop
        } else {
            Flow::Continue
        })
    })
    .expect("control loop");
    assert_eq!(summary.ticks, WARM_UP_TICKS + TICKS - 1);
    assert_eq!(received, 2 * (WARM_UP_TICKS + TICKS));
    assert!(
        heartbeats_counted >= 1,
        "no heartbeat among the counted ticks"
    );
    assert_eq!(
        allocations, samples_sent_counted,
        "{allocations} allocations for {samples_sent_counted} samples sent in {TICKS} ticks and \
         {heartbeats_counted} heartbeat(s): only iceoryx2's one block per loan is expected"
    );
}
