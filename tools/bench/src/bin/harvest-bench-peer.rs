//! Stand-alone front end of harvest-bench with the same command shape as the `harvest` binary
//! (`bench ipc ...` and the hidden `bench-peer ...`), so the benchmark can spawn itself as the
//! peer in tests before (and independently of) the `harvest` CLI.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

use clap::{Parser, Subcommand};
use harvest_bench::{BenchIpcArgs, BenchPeerArgs, run_bench_ipc, run_bench_peer};
use std::process::ExitCode;

#[derive(Parser)]
#[command(name = "harvest-bench-peer", about = "harvest transport benchmarks")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Benchmarks.
    Bench {
        #[command(subcommand)]
        bench: Bench,
    },
    /// The sending process of one benchmark case (started by `bench ipc`).
    #[command(name = "bench-peer", hide = true)]
    BenchPeer(BenchPeerArgs),
}

#[derive(Subcommand)]
enum Bench {
    /// One-way inter-process latency: our layer vs raw iceoryx2 vs a copying socket.
    Ipc(BenchIpcArgs),
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .with_writer(std::io::stderr)
        .init();
    let result = match Cli::parse().command {
        Command::Bench {
            bench: Bench::Ipc(args),
        } => run_bench_ipc(&args).map(|report| {
            print!("{}", report.table());
        }),
        Command::BenchPeer(args) => run_bench_peer(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error}");
            ExitCode::FAILURE
        }
    }
}
