//! `harvest`: the command-line tool and the entry point of every process of the stack.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

mod cli;

use clap::Parser;

fn main() -> std::process::ExitCode {
    let cli = cli::Cli::parse();
    let process_name = cli.process_name();
    cli::logging::init(&process_name);
    match cli.run(&process_name) {
        Ok(code) => code,
        Err(error) => {
            tracing::error!("{error:#}");
            eprintln!("harvest {process_name}: error: {error:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
