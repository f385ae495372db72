//! Stand-alone `harvest eval perception` for measuring before the CLI is wired:
//! `cargo run -p harvest-eval --release --example eval_perception -- --frames 30`.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

use clap::Parser;
use harvest_eval::{EvalPerceptionArgs, run_eval_perception};

#[derive(Parser)]
struct Cli {
    #[command(flatten)]
    args: EvalPerceptionArgs,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_writer(std::io::stderr)
        .init();
    run_eval_perception(&Cli::parse().args)?;
    Ok(())
}
