//! Tracing setup shared by every process: env filter (`RUST_LOG`, default `info`), stderr,
//! and the process name on every line (through the `proc` span entered in `main`).

use tracing_subscriber::EnvFilter;

pub fn init(_process_name: &str) {
    let filter = EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new("info"));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_target(false)
        .compact()
        .try_init();
}
