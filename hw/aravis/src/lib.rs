//! Aravis 0.8 (GigE Vision and USB3 Vision through GenICam) loaded at run time, behind safe
//! types: [`Camera`], its [`Stream`] and [`Buffer`]s, and Aravis's fake GigE Vision camera
//! ([`FakeCamera`]) for tests and benchmarks.
//!
//! The library is opened with `dlopen` ([`Aravis::load`]) rather than linked, so the stack
//! builds and runs on a machine without Aravis; only what opens a camera needs it, and it then
//! fails naming the library and the package to install. All `unsafe` of the GigE camera driver
//! lives in this crate, each block with the C contract it relies on.

#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]
#![deny(missing_docs)]
#![deny(unsafe_op_in_unsafe_fn)]

pub mod camera;
pub mod error;
pub mod fake;
pub mod library;
pub mod pixel_format;

pub use camera::{Buffer, BufferStatus, Camera, Stream, StreamStatistics};
pub use error::AravisError;
pub use fake::{FakeCamera, FakeImage, LoopbackCameraLock};
pub use library::{Aravis, LIBRARY};
