//! `harvest foxglove`: a Foxglove WebSocket server (`ws://127.0.0.1:8765` by default) showing
//! the stack's channels through the one mapping of `harvest-foxglove-mapping`.
//!
//! - [`bridge`]: the process: the ipc wait set wakes on every mapped channel (no polling),
//!   applies the viewing rates and hands messages to the server's channels.
//! - [`camera_thread`]: camera frames on a thread (and iceoryx2 node) of their own, read in
//!   place from shared memory, downscaled and JPEG-encoded only while a client watches.
//! - [`server`]: the SDK's server in a one-worker tokio runtime; per-client queues that drop the
//!   oldest message when a client is slow; the channels the mapping writes to.
//! - [`args`]: the command line.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod args;
pub mod bridge;
pub mod camera_thread;
pub mod server;

pub use args::FoxgloveArgs;
pub use bridge::{BridgeError, run, run_until};
