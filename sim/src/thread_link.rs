//! What the simulator's two threads share: the stop request, the physics tick count and the
//! newest consistent snapshot of the moving part of the world.
//!
//! The physics thread ([`crate::physics_thread`]) owns the [`SimRobot`](crate::robot::SimRobot)
//! and steps it at 200 Hz; the render thread ([`crate::render_thread`]) keeps its own copy of
//! the [`World`] for the camera, ALACS and LiDAR renderers. After every step the physics thread
//! copies what a step can change and a renderer can see (each apple's centre and state) into
//! the snapshot; before every render the render thread copies the snapshot into its world. Both
//! copies run under the snapshot's lock, so a render sees the world as one physics step left
//! it. The physics thread only ever *tries* the lock: when the render thread holds it (for the
//! copy, never for a render), that step's snapshot is skipped and the next step's is published,
//! so the physics never waits for the render thread.
//!
//! Leaves, branches, the backdrop and the scenario move only when the robot moves (trailer,
//! platform): the snapshot carries the robot's offset and the render copy follows it
//! ([`World::set_robot_offset_m`]). The vacuum and contact state of the render copy is not kept up
//! to date: no renderer reads it (the renderers draw no arms either).

use crate::orchard::{AppleState, World};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Mutex, MutexGuard, TryLockError};

/// The moving part of the world after one physics step.
#[derive(Debug, Clone, PartialEq)]
pub struct WorldSnapshot {
    /// Per apple, in the world's order: centre in the robot frame (m) and state.
    apples: Vec<([f64; 3], AppleState)>,
    /// Where the robot stood in the row frame (see [`crate::world_motion`]), m.
    robot_offset_m: [f64; 3],
    /// Physics steps taken when the snapshot was taken (0: the generated world).
    physics_tick: u64,
    /// Simulated time of the snapshot, ns.
    sim_time_ns: u64,
    /// Stack-clock time of the step that produced it, ns (0: the generated world).
    stamp_ns: u64,
}

impl WorldSnapshot {
    fn of(world: &World) -> Self {
        let mut snapshot = Self {
            apples: Vec::with_capacity(world.apples().len()),
            robot_offset_m: world.robot_offset_m(),
            physics_tick: 0,
            sim_time_ns: 0,
            stamp_ns: 0,
        };
        snapshot.copy_from(world);
        snapshot
    }

    /// Copies the apples of `world` in place (no allocation once sized).
    fn copy_from(&mut self, world: &World) {
        self.robot_offset_m = world.robot_offset_m();
        self.apples.clear();
        self.apples.extend(
            world
                .apples()
                .iter()
                .map(|apple| (apple.center_in_robot_m, apple.state)),
        );
    }
}

/// Where a synchronised render copy of the world stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SnapshotStamp {
    /// Physics steps behind the copy.
    pub physics_tick: u64,
    /// Simulated time of the copy, ns.
    pub sim_time_ns: u64,
    /// Stack-clock time of the step behind the copy, ns (0: the generated world).
    pub stamp_ns: u64,
}

/// The link between the physics thread and the render thread (see the module documentation).
#[derive(Debug)]
pub struct ThreadLink {
    stop: AtomicBool,
    physics_ticks: AtomicU64,
    snapshot: Mutex<WorldSnapshot>,
}

impl ThreadLink {
    /// A link whose snapshot is `world` as generated.
    pub fn new(world: &World) -> Self {
        Self {
            stop: AtomicBool::new(false),
            physics_ticks: AtomicU64::new(0),
            snapshot: Mutex::new(WorldSnapshot::of(world)),
        }
    }

    /// Asks both threads to end at their next wake-up.
    pub fn request_stop(&self) {
        self.stop.store(true, Ordering::SeqCst);
    }

    /// True once either thread ended or [`Self::request_stop`] was called.
    pub fn stop_requested(&self) -> bool {
        self.stop.load(Ordering::SeqCst)
    }

    /// A guard that requests the stop when dropped: a thread holds one for its whole run, so
    /// its end (return, error or panic) ends the other thread too.
    pub fn stop_on_drop(&self) -> StopOnDrop<'_> {
        StopOnDrop { link: self }
    }

    /// Physics steps taken so far.
    pub fn physics_ticks(&self) -> u64 {
        self.physics_ticks.load(Ordering::SeqCst)
    }

    /// Physics side, after each step: counts the step and publishes the world's moving state,
    /// unless the render thread holds the snapshot right now (then the next step's is used).
    /// Returns whether the snapshot was published. Never blocks.
    pub fn publish_step(&self, world: &World, sim_time_ns: u64, stamp_ns: u64) -> bool {
        let physics_tick = self.physics_ticks.fetch_add(1, Ordering::SeqCst) + 1;
        let mut snapshot = match self.snapshot.try_lock() {
            Ok(guard) => guard,
            Err(TryLockError::Poisoned(poisoned)) => poisoned.into_inner(),
            Err(TryLockError::WouldBlock) => return false,
        };
        snapshot.copy_from(world);
        snapshot.physics_tick = physics_tick;
        snapshot.sim_time_ns = sim_time_ns;
        snapshot.stamp_ns = stamp_ns;
        true
    }

    /// Render side, before each render: brings the apples of the render copy `world` to the
    /// newest published step. `world` must be a copy of the world the link was made from.
    pub fn sync_world(&self, world: &mut World) -> SnapshotStamp {
        let snapshot = self.lock_snapshot();
        // Moves the leaves, branches and backdrop of the render copy with the robot.
        world.set_robot_offset_m(snapshot.robot_offset_m);
        for (apple, (center_in_robot_m, state)) in world.apples.iter_mut().zip(&snapshot.apples) {
            apple.center_in_robot_m = *center_in_robot_m;
            apple.state = *state;
        }
        SnapshotStamp {
            physics_tick: snapshot.physics_tick,
            sim_time_ns: snapshot.sim_time_ns,
            stamp_ns: snapshot.stamp_ns,
        }
    }

    /// The lock (the snapshot is plain data: a thread that panicked while holding it left a
    /// complete older or newer copy, still usable).
    fn lock_snapshot(&self) -> MutexGuard<'_, WorldSnapshot> {
        self.snapshot
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

/// Requests the stop of both threads when dropped (see [`ThreadLink::stop_on_drop`]).
#[derive(Debug)]
pub struct StopOnDrop<'link> {
    link: &'link ThreadLink,
}

impl Drop for StopOnDrop<'_> {
    fn drop(&mut self) {
        self.link.request_stop();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::{ArmId, StepInputs};
    use crate::robot::SimRobot;
    use crate::scenario::Scenario;

    fn robot() -> SimRobot {
        SimRobot::new(&Scenario::preset("ideal").expect("ideal"), 3).expect("robot")
    }

    #[test]
    fn a_synced_copy_has_the_apples_of_the_published_step() {
        let mut robot = robot();
        let link = ThreadLink::new(robot.world());
        let mut render_copy = robot.world().clone();
        // Move the physics world on: knock an apple down by hand, step a while.
        robot.set_valves(StepInputs::valves_for_arms([true, false]));
        for _ in 0..20 {
            robot.step(0.005).expect("step");
        }
        let mut physics_world = robot.world().clone();
        physics_world.apples[0].state = AppleState::Attached {
            arm: ArmId::Arm1,
            detached: false,
        };
        physics_world.apples[0].center_in_robot_m = [1.0, 2.0, 3.0];
        physics_world.apples[1].state = AppleState::Dropped;
        assert!(link.publish_step(&physics_world, 100_000_000, 42));
        assert_ne!(render_copy.apples(), physics_world.apples());
        let stamp = link.sync_world(&mut render_copy);
        assert_eq!(render_copy.apples(), physics_world.apples());
        assert_eq!(
            stamp,
            SnapshotStamp {
                physics_tick: 1,
                sim_time_ns: 100_000_000,
                stamp_ns: 42,
            }
        );
        assert_eq!(link.physics_ticks(), 1);
        // Static parts are untouched.
        assert_eq!(render_copy.leaves(), robot.world().leaves());
    }

    #[test]
    fn the_physics_side_never_waits_for_a_held_snapshot() {
        let robot = robot();
        let link = ThreadLink::new(robot.world());
        let held = link.lock_snapshot();
        // The render side holds the lock: the step is counted, its snapshot skipped.
        assert!(!link.publish_step(robot.world(), 5_000_000, 1));
        assert_eq!(link.physics_ticks(), 1);
        assert_eq!(held.physics_tick, 0);
        drop(held);
        assert!(link.publish_step(robot.world(), 10_000_000, 2));
        let mut copy = robot.world().clone();
        assert_eq!(link.sync_world(&mut copy).physics_tick, 2);
    }

    #[test]
    fn a_dropped_guard_requests_the_stop() {
        let link = ThreadLink::new(robot().world());
        assert!(!link.stop_requested());
        drop(link.stop_on_drop());
        assert!(link.stop_requested());
    }
}
