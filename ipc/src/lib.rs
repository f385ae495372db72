//! The one channel catalogue of the harvest stack and its typed zero-copy transport on iceoryx2.
//!
//! - [`catalogue`]: every channel (topic, payload type, QoS), declared once.
//! - [`payloads`]: the `#[repr(C)]` message types, each starting with a [`Header`].
//! - [`Context`], [`Publisher`], [`Subscriber`], [`Waiter`]: typed ports and the event loop.
//! - [`clock`]: which clock stamps mean, and the clocks process logic is handed.
//! - [`codec`]: the one encoding used by recordings and copying transports.

#[cfg(feature = "testing")]
pub mod allocation_counter;
pub mod bounded_vec;
pub mod camera_model;
pub mod catalogue;
pub mod cleanup;
pub mod clock;
pub mod codec;
pub mod config_file;
pub mod context;
pub mod control_loop;
pub mod domain;
pub mod duration;
pub mod error;
pub mod failure_streak;
pub mod fixed_string;
pub mod header;
pub mod health;
pub mod memory_lock;
pub mod payload;
pub mod payloads;
pub mod period_stats;
pub mod periodic_timer;
pub mod publisher;
pub mod subscriber;
pub mod termination;
pub mod waiter;

pub use bounded_vec::BoundedVec;
pub use catalogue::{ArmId, Channel, ChannelSpec, ChannelVisitor, Qos};
pub use clock::{Clock, ManualClock, MonotonicClock};
pub use context::{Context, Ipc};
pub use domain::Domain;
pub use fixed_string::FixedString;
pub use header::Header;
pub use health::{HEARTBEAT_PERIOD, HealthReporter};
pub use payload::Payload;
pub use publisher::{Loan, Publisher};
pub use subscriber::{Received, Subscriber};
pub use waiter::{Flow, RunEnd, RunError, Waiter};

/// Re-exported so processes attach listeners and intervals without naming iceoryx2 paths.
pub use iceoryx2::prelude::{WaitSetAttachmentId, WaitSetGuard};
