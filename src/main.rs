//! `harvest`: the command-line tool and the entry point of every process of the stack.

mod cli;

use clap::Parser;

fn main() -> std::process::ExitCode {
    let cli = cli::Cli::parse();
    let process_name = cli.process_name();
    cli::logging::init(&process_name);
    let span = tracing::info_span!("proc", name = %process_name);
    let _entered = span.enter();
    match cli.run(&process_name) {
        Ok(code) => code,
        Err(error) => {
            tracing::error!("{error:#}");
            eprintln!("harvest {process_name}: error: {error:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
