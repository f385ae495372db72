//! The one channel catalogue of the harvest stack and its typed zero-copy transport on iceoryx2.
//!
//! - [`catalogue`]: every channel (topic, payload type, QoS), declared once.
//! - [`payloads`]: the `#[repr(C)]` message types, each starting with a [`Header`].
//! - [`Context`], [`Publisher`], [`Subscriber`], [`Waiter`]: typed ports and the event loop.
//! - [`clock`]: which clock stamps mean, and the clocks process logic is handed.
//! - [`codec`]: the one encoding used by recordings and copying transports.
//! - [`schema`]: each payload's schema, generated from its type, as recordings store it.
//! - [`any_bit_pattern`], [`wire_code`]: the payload memory contract, checked at compile time, and
//!   enums carried as typed codes.
//! - [`termination`]: the one SIGINT/SIGTERM mechanism of every loop.

#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]
#![deny(missing_docs)]

// The derives name `::harvest_ipc::...`; this lets them work inside this crate too.
extern crate self as harvest_ipc;

#[cfg(feature = "testing")]
pub mod allocation_counter;
pub mod any_bit_pattern;
pub mod arm_id;
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
pub mod heap_trim;
pub mod memory_lock;
// The operator channels' client side.
pub mod operator_client;
pub mod payload;
pub mod payloads;
pub mod period_stats;
pub mod periodic_timer;
pub mod proc_status;
pub mod publisher;
pub mod schema;
pub mod scratch_domain;
pub mod subscriber;
pub mod termination;
pub mod waiter;
pub mod wire_code;

pub use any_bit_pattern::AnyBitPattern;
pub use arm_id::ArmId;
pub use bounded_vec::BoundedVec;
pub use catalogue::{Channel, ChannelSpec, ChannelVisitor, Qos};
pub use clock::{Clock, ManualClock, MonotonicClock};
pub use context::{Context, Ipc};
pub use domain::Domain;
pub use fixed_string::FixedString;
pub use header::Header;
pub use health::{HEARTBEAT_PERIOD, HealthReporter};
pub use payload::Payload;
pub use publisher::{Loan, Publisher};
pub use scratch_domain::ScratchDomain;
pub use subscriber::{Received, Subscriber};
pub use waiter::{Flow, RunEnd, RunError, Waiter};
pub use wire_code::{UnknownCode, WireCode, WireEnum};

/// `#[derive(AnyBitPattern)]`, `#[derive(Describe)]`, `#[derive(Payload)]` and
/// `#[derive(WireEnum)]` (see the traits of the same names).
pub use harvest_ipc_derive::{AnyBitPattern, Describe, Payload, WireEnum};
pub use schema::Describe;

/// What the derives' generated code names; not part of the API.
#[doc(hidden)]
pub mod __private {
    pub use serde_json;
}

/// Re-exported so processes attach listeners and intervals without naming iceoryx2 paths.
pub use iceoryx2::prelude::{WaitSetAttachmentId, WaitSetGuard};
